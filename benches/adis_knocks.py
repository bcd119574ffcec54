"""The knocks in an ADIS16405 log: a copy with them cut out, to measure how much of the
gap they leave (issue 27, run 4).

A knock is a run of samples whose first difference of the target gyro channel lies more
than 8 robust standard deviations (1.4826 MAD of the differences) from its median; each
is widened by 5 samples on either side (the filter's ringing), overlapping spans merged.
Every channel of a span is replaced by the same channels 1000 samples earlier (10 s at
100 Hz), so the copy keeps the sensor's noise, resolution and cross-axis coupling.
Usage: python3 benches/adis_knocks.py IN.parquet OUT.parquet [CHANNEL]
Prints the spans (samples, seconds) and each channel's largest |first difference| in them.
"""
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

src, dst = sys.argv[1], sys.argv[2]
ch = sys.argv[3] if len(sys.argv) > 3 else "gyro_x_dps"
t = pq.read_table(src)
fs = float((t.schema.metadata or {}).get(b"sample_rate_hz", b"100"))
d = np.diff(t.column(ch).to_numpy())
z = np.abs(d - np.median(d)) / (1.4826 * np.median(np.abs(d - np.median(d))))
spans = []
for i in np.flatnonzero(z > 8.0):
    a, b = max(i - 5, 1000), min(i + 7, len(d) + 1)
    if spans and a <= spans[-1][1]:
        spans[-1][1] = max(spans[-1][1], b)
    else:
        spans.append([a, b])
cols = {}
for c in t.column_names:
    x = t.column(c).to_numpy().copy()
    for a, b in spans:
        x[a:b] = x[a - 1000 : b - 1000]
    cols[c] = x
for a, b in spans:
    big = {c: float(np.abs(np.diff(t.column(c).to_numpy()[a - 1 : b])).max()) for c in t.column_names}
    print(f"span {a}..{b} ({a / fs:.2f}-{b / fs:.2f} s):", ", ".join(f"{c} {v:.3g}" for c, v in big.items()))
pq.write_table(pa.table(cols).replace_schema_metadata(t.schema.metadata), dst)
