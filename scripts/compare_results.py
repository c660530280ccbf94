#!/usr/bin/env python3
"""Compares the result.h5 files of two run directories dataset by dataset, bit for bit.

    .venv/bin/python scripts/compare_results.py runs/before runs/after

For every case directory present in both, every dataset of the first file must exist in the
second with the same shape, dtype and bytes (NaN equal to NaN of the same bits). Datasets only
the second file has are listed as added (a new output, not a change). Attributes are not
compared: they carry versions and wall times. Exit code 1 when any dataset differs or is
missing.
"""
import sys
from pathlib import Path

import h5py
import numpy as np


def datasets(f):
    out = {}
    f.visititems(lambda name, obj: out.__setitem__(name, obj) if isinstance(obj, h5py.Dataset) else None)
    return out


def same(a, b):
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    x, y = a[()], b[()]
    if isinstance(x, np.ndarray) and x.dtype.kind in "fiub":
        return x.tobytes() == y.tobytes()
    return np.array_equal(np.asarray(x, dtype=object), np.asarray(y, dtype=object))


def main(before, after):
    failed, compared, added = 0, 0, set()
    for old in sorted(Path(before).rglob("result.h5")):
        new = Path(after) / old.relative_to(before)
        if not new.exists():
            print(f"missing: {new}")
            failed += 1
            continue
        with h5py.File(old, "r") as fa, h5py.File(new, "r") as fb:
            a, b = datasets(fa), datasets(fb)
            added |= set(b) - set(a)
            for name, ds in a.items():
                compared += 1
                if name not in b:
                    print(f"{old.relative_to(before)}: {name} missing")
                    failed += 1
                elif not same(ds, b[name]):
                    print(f"{old.relative_to(before)}: {name} differs")
                    failed += 1
    print(f"{compared} datasets compared, {failed} differ or are missing; added in the second: {sorted(added) or 'none'}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
