"""Reads every table of a `farma batch` dataset with DuckDB, pyarrow.dataset and pandas,
one call each, and checks that every row carries `log_id` and `channel` (issue 26's bar).

    python3 benches/read_dataset.py ROOT

Prints one line per table: rows read by each reader and whether they agree; exits 1 when
a reader fails, the row counts differ, or a row lacks log_id or channel. Needs duckdb,
pyarrow and pandas (pip install duckdb pyarrow pandas).
"""
import os
import sys

import duckdb
import pandas as pd
import pyarrow.dataset as ds

root = sys.argv[1]
tables = sorted(
    d for d in os.listdir(root)
    if os.path.isdir(os.path.join(root, d)) and not d.startswith(("_", "."))
)
bad = 0
for t in tables:
    glob = os.path.join(root, t, "**", "*.parquet")
    try:
        con = duckdb.connect()
        n_duck, n_log, n_chan = con.execute(
            f"select count(*), count(log_id), count(channel) from read_parquet('{glob}', hive_partitioning = true)"
        ).fetchone()
        tab = ds.dataset(os.path.join(root, t), format="parquet", partitioning="hive").to_table()
        n_arrow = tab.num_rows
        df = pd.read_parquet(os.path.join(root, t))
        n_pandas = len(df)
        ok = (
            n_duck == n_arrow == n_pandas
            and n_log == n_duck
            and n_chan == n_duck
            and df["log_id"].notna().all()
            and df["channel"].notna().all()
        )
    except Exception as e:  # a reader that fails is a failure of the dataset
        print(f"{t}: FAILED: {e}")
        bad = 1
        continue
    print(f"{t}: duckdb {n_duck} rows (log_id on {n_log}, channel on {n_chan}), pyarrow {n_arrow}, pandas {n_pandas}: {'ok' if ok else 'MISMATCH'}")
    bad |= not ok
m = pd.read_parquet(os.path.join(root, "manifest.parquet"))
print(f"manifest.parquet: {len(m)} units, status {m['status'].value_counts().to_dict()}")
sys.exit(bad)
