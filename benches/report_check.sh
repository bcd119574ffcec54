#!/usr/bin/env bash
# Renders farma's report.html pages in a real browser (headless Chromium) and fails on
# a page that does not render: a console error, a blank screenshot (almost one colour),
# or a DOM without the plots' SVG. Not run by `cargo test` (it needs a browser).
#
# Needs Chromium and python3 (the PNG check uses its standard library only). Installs
# nothing itself; on Debian/Ubuntu:
#     apt-get install -y chromium-headless-shell     # or: apt-get install -y chromium
#
# Usage:
#     benches/report_check.sh PNG_DIR REPORT.html [REPORT.html ...]
#     benches/report_check.sh PNG_DIR --run         # runs the three reports of issue 28
# With --run it writes (with the farma on PATH, else target/release/farma):
#     farma analyze fixtures/multiaxis.csv -o PNG_DIR/runs/analyze
#     farma adev ../shared/realdata/imudata-adis16405/adis_16405_imu1.parquet \
#         --channel gyro_x_dps -o PNG_DIR/runs/adev
#     farma gap --real ../shared/realdata/imudata-adis16405/adis_16405_imu1.parquet \
#         --sim fixtures/specs/adis16405_datasheet.toml --channel gyro_x_dps \
#         --replicas 10 -o PNG_DIR/runs/gap
# and checks their report.html. Each page gives PNG_DIR/<name>.png (the name from the
# report's folder); exit 1 when any page fails, with the reason on stderr.
set -euo pipefail

if [ $# -lt 2 ]; then
    sed -n '2,22p' "$0" >&2
    exit 2
fi
out=$1
shift
mkdir -p "$out"

browser=""
for b in chromium-headless-shell chrome-headless-shell chromium chromium-browser google-chrome; do
    if command -v "$b" >/dev/null 2>&1; then
        browser=$(command -v "$b")
        break
    fi
done
if [ -z "$browser" ] && [ -x /usr/lib/chromium/chrome-headless-shell ]; then
    browser=/usr/lib/chromium/chrome-headless-shell
fi
if [ -z "$browser" ]; then
    echo "report_check: no Chromium found; apt-get install -y chromium-headless-shell" >&2
    exit 2
fi

pages=()
if [ "$1" = "--run" ]; then
    farma=$(command -v farma || echo target/release/farma)
    runs="$out/runs"
    adis=../shared/realdata/imudata-adis16405/adis_16405_imu1.parquet
    "$farma" analyze fixtures/multiaxis.csv -o "$runs/analyze" >/dev/null
    "$farma" adev "$adis" --channel gyro_x_dps -o "$runs/adev" >/dev/null
    "$farma" gap --real "$adis" --sim fixtures/specs/adis16405_datasheet.toml \
        --channel gyro_x_dps --replicas 10 -o "$runs/gap" >/dev/null
    pages=("$runs/analyze/report.html" "$runs/adev/report.html" "$runs/gap/report.html")
else
    pages=("$@")
fi

# Checks a PNG: fails when one colour covers more than 99.5 % of it.
png_check() {
    python3 - "$1" <<'PY'
import struct, sys, zlib
path = sys.argv[1]
data = open(path, "rb").read()
if data[:8] != b"\x89PNG\r\n\x1a\n":
    sys.exit(f"{path}: not a PNG")
pos, idat, w = 8, [], 0
while pos < len(data):
    n, kind = struct.unpack(">I4s", data[pos:pos + 8])
    body = data[pos + 8:pos + 8 + n]
    if kind == b"IHDR":
        w, h, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", body)
        if depth != 8 or ctype not in (2, 6) or interlace:
            sys.exit(f"{path}: PNG kind not handled (depth {depth}, colour type {ctype})")
        bpp = 3 if ctype == 2 else 4
    elif kind == b"IDAT":
        idat.append(body)
    pos += 12 + n
raw = zlib.decompress(b"".join(idat))
stride = w * bpp
prev = bytearray(stride)
counts = {}
for r in range(h):
    f = raw[r * (stride + 1)]
    line = bytearray(raw[r * (stride + 1) + 1:(r + 1) * (stride + 1)])
    if f == 1:
        for i in range(bpp, stride):
            line[i] = (line[i] + line[i - bpp]) & 255
    elif f == 2:
        line = bytearray((a + b) & 255 for a, b in zip(line, prev))
    elif f == 3:
        for i in range(stride):
            left = line[i - bpp] if i >= bpp else 0
            line[i] = (line[i] + ((left + prev[i]) >> 1)) & 255
    elif f == 4:
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            p = a + b - c
            pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
            pr = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            line[i] = (line[i] + pr) & 255
    prev = line
    # count colours on every 4th row and column (enough to see a blank page)
    if r % 4 == 0:
        for i in range(0, stride, 4 * bpp):
            key = bytes(line[i:i + 3])
            counts[key] = counts.get(key, 0) + 1
total = sum(counts.values())
top = max(counts.values())
share = top / total
print(f"{path}: {w}x{h}, {len(counts)} colours sampled, the commonest on {100 * share:.1f} %")
if share > 0.995 or len(counts) < 8:
    sys.exit(f"{path}: blank (one colour on {100 * share:.1f} % of the page)")
PY
}

fail=0
for page in "${pages[@]}"; do
    if [ ! -f "$page" ]; then
        echo "report_check: $page: no such file" >&2
        fail=1
        continue
    fi
    name=$(basename "$(dirname "$(realpath "$page")")")
    png="$out/$name.png"
    url="file://$(realpath "$page")"
    log="$out/$name.console.log"
    # the whole page: tall enough for the plots; the console on stderr
    "$browser" --headless --no-sandbox --disable-gpu --hide-scrollbars \
        --enable-logging=stderr --v=0 --window-size=1280,5200 \
        --screenshot="$png" "$url" >"$log" 2>&1 || {
        echo "report_check: $page: Chromium failed (see $log)" >&2
        fail=1
        continue
    }
    if grep -E "Uncaught|:CONSOLE|CONSOLE\(" "$log" >&2; then
        echo "report_check: $page: console messages (above)" >&2
        fail=1
    fi
    dom=$("$browser" --headless --no-sandbox --disable-gpu --dump-dom "$url" 2>/dev/null)
    n_svg=$(grep -o "<svg" <<<"$dom" | wc -l || true)
    if [ "$n_svg" -lt 1 ]; then
        echo "report_check: $page: the rendered page holds no <svg>" >&2
        fail=1
    fi
    if [ ! -s "$png" ]; then
        echo "report_check: $page: no screenshot" >&2
        fail=1
        continue
    fi
    png_check "$png" || fail=1
    echo "report_check: $page: $n_svg plots rendered -> $png" >&2
done
exit $fail
