#!/usr/bin/env bash
# Runs the mutation fuzzer (examples/fuzz.rs) on TARGET for SECONDS in all, restarting
# it after an abort (an allocation failure, a stack overflow: no Rust code catches
# those) and keeping the input that caused it as OUT/abort-N.bin.
#   bash benches/fuzz.sh TARGET SECONDS     TARGET: csv parquet arrow spec store
# Findings go to $FUZZ_OUT (default target/fuzz/TARGET): crash-N.bin (a panic),
# abort-N.bin (the process died), hang.bin (over 10 s).
set -u
target=${1:?target: csv parquet arrow spec store}
secs=${2:?seconds}
root=$(cd "$(dirname "$0")/.." && pwd)
out=${FUZZ_OUT:-$root/target/fuzz/$target}
mkdir -p "$out"
# FUZZ_NO_BUILD=1: use the binary as built (while other builds hold the target dir)
[ "${FUZZ_NO_BUILD:-0}" = 1 ] || cargo build --release --example fuzz --manifest-path "$root/Cargo.toml" || exit 1
bin=${CARGO_TARGET_DIR:-$root/target}/release/examples/fuzz
end=$(( $(date +%s) + secs ))
aborts=0
while [ "$(date +%s)" -lt "$end" ]; do
  left=$(( end - $(date +%s) ))
  "$bin" "$target" "$left" "$out"
  rc=$?
  case $rc in
    0|1) ;;                                   # done (1: panics saved as crash-N.bin)
    3) echo "fuzz.sh: hang saved in $out/hang.bin"; exit 3 ;;
    *) aborts=$((aborts + 1))
       [ -f "$out/current.bin" ] && mv "$out/current.bin" "$out/abort-$aborts.bin"
       echo "fuzz.sh: exit $rc (abort); input kept as $out/abort-$aborts.bin" ;;
  esac
done
ls "$out"/crash-*.bin "$out"/abort-*.bin 2>/dev/null && exit 1
exit 0
