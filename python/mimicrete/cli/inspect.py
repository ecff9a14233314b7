"""`mimicrete inspect` (temporary forwarder while the package is regrouped)."""

from __future__ import annotations

import argparse


def configure(parser: argparse.ArgumentParser) -> None:
    import mimicrete.demos as lib

    lib.configure(parser)


def main(args: argparse.Namespace) -> int:
    import mimicrete.demos as lib

    return int(lib.main(args) or 0)
