"""`mimicrete train` (temporary forwarder while the package is regrouped)."""

from __future__ import annotations

import argparse


def configure(parser: argparse.ArgumentParser) -> None:
    import mimicrete.learn.train as lib

    lib.configure(parser)


def main(args: argparse.Namespace) -> int:
    import mimicrete.learn.train as lib

    return int(lib.main(args) or 0)
