"""``python -m mimicrete.bench [AREA ...]``: run every benchmark (or the named areas) and print."""

from __future__ import annotations

import argparse
import importlib
import sys
import time

AREAS = ["kin", "sim", "demo", "teleop", "teleop_live", "gestures", "train"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("areas", nargs="*", default=AREAS, help=f"subset of {AREAS}")
    args = parser.parse_args()
    unknown = [a for a in args.areas if a not in AREAS]
    if unknown:
        parser.error(f"unknown area(s) {', '.join(unknown)}: choose from {', '.join(AREAS)}")
    failed = []
    for area in args.areas:
        print(f"\n== {area} ==", flush=True)
        t0 = time.perf_counter()
        try:
            # every area's module ships with the package: one that does not import (a peer
            # missing: `make bench` installs requirements/bench.txt) is a failed benchmark
            importlib.import_module(f"mimicrete.bench.{area}").run()
        except Exception as e:  # a broken benchmark must not hide the others
            failed.append(area)
            print(f"!! {area} failed: {type(e).__name__}: {e}")
        print(f"   ({area} took {time.perf_counter() - t0:.1f} s)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
