"""`mimicrete inspect FILE.mcap ...`: what is in each demo (channels, message counts, metadata,
attachments, duration and step count, read by :func:`mimicrete.demos.inspect` with the official
``mcap`` reader) and, unless ``--no-verify``, every chunk's CRC (:func:`mimicrete.demos.verify`).
Exit 1 when a file is damaged or not a demo; ``--json`` prints one JSON object per file."""

from __future__ import annotations

import argparse
import json
from typing import Any


def _print_report(info: dict[str, Any]) -> None:
    sizes = f"{info['bytes']} bytes, {info['chunks']} chunks, {info['messages']} messages"
    print(f"{info['path']}  ({sizes})")
    ep = info["metadata"].get("episode") or info["metadata"].get("episode_start") or {}
    print(
        f"  task={ep.get('task', '?')} episode={ep.get('episode', '?')} seed={ep.get('seed', '?')} "
        f"robot={ep.get('robot_model', '?')} steps={info['steps']} "
        f"duration={info['duration_s']:.3f} s success={info['success']}"
        + ("" if info["finished"] else "  [NOT FINISHED: no 'episode' record]")
    )
    print("  channels:")
    width = max((len(c["topic"]) for c in info["channels"]), default=5)
    for c in info["channels"]:
        print(
            f"    {c['topic']:<{width}}  {c['messages']:>7}  {c['schema']} "
            f"({c['message_encoding']}/{c['schema_encoding']})"
        )
    print("  metadata:")
    for name, md in info["metadata"].items():
        print(f"    {name}:")
        for k, v in sorted(md.items()):
            print(f"      {k} = {v}")
    print("  attachments:")
    for a in info["attachments"]:
        print(f"    {a['name']}  {a['media_type']}  {a['bytes']} bytes")
    if info["stages_error"]:
        print(f"  stage times: unreadable ({info['stages_error']})")
    if info["stages"]:
        print("  stage times (ms, over the control steps where both times are known):")
        width = max(len(k) for k in info["stages"])
        print(f"    {'stage':<{width}}  {'p50':>8}  {'p99':>8}  {'steps':>6}")
        for name, d in info["stages"].items():
            print(f"    {name:<{width}}  {d['p50']:>8.2f}  {d['p99']:>8.2f}  {d['n']:>6}")


def _deploy_summary(f: str, info: dict[str, Any] | None) -> dict[str, Any] | None:
    """A ``mimicrete deploy`` log's tick summary (gates, latency), None for other demos."""
    if info is None or not any(c["topic"] == "/deploy/tick" for c in info["channels"]):
        return None
    from mimicrete.robot.deploy import summary

    return summary(f)


def _print_deploy(d: dict[str, Any]) -> None:
    print(
        f"  deploy: {d['ticks']} ticks, {d['sent']} commands sent, "
        f"{d['gated_ticks']} ticks with a gate fired"
    )
    gates = ", ".join(f"{g} {n}" for g, n in sorted(d["gates"].items())) or "none fired"
    print(f"    gates: {gates}")
    srcs = ", ".join(f"{s} {n}" for s, n in sorted(d["tile_sources"].items()))
    print(f"    tile pose from: {srcs}")
    lat = d["latency_ms"]
    if lat:
        print(
            f"    read -> command latency (ms): p50 {lat['p50']:.2f}, p99 {lat['p99']:.2f}, "
            f"max {lat['max']:.2f}"
        )
    print(f"    stopped: {d['stop_reason'] or 'unknown (the log was not finished)'}")


def _print_integrity(f: str, rep: dict[str, Any]) -> None:
    chunks = rep["chunks"]
    if rep["ok"]:
        print(f"  integrity: OK ({len(chunks)} chunks, every CRC checked)")
        return
    bad = [c for c in chunks if c["error"] is not None]
    lost = rep["messages_lost"]
    print(
        f"  integrity: DAMAGED ({len(bad)} of {len(chunks)} chunks damaged, "
        f"{'an unknown number of' if lost is None else lost} messages lost)"
    )
    for line in rep["problems"]:
        print(f"    {line}")
    print(f"  recover the intact chunks: mimicrete.demos.salvage_to({f!r}, 'fixed.mcap')")


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("files", nargs="+", metavar="FILE.mcap", help="demo file(s) to inspect")
    parser.add_argument("--json", action="store_true", help="print one JSON object per file")
    parser.add_argument(
        "--no-verify",
        dest="verify",
        action="store_false",
        help="read only the summary; skip checking every chunk's CRC (by default a damaged "
        "chunk is reported and the exit code is 1)",
    )


def main(args: argparse.Namespace) -> int:
    from mimicrete import LogFormatError, demos

    status = 0
    for f in args.files:
        rep: dict[str, Any] | None = None
        if getattr(args, "verify", True):
            try:
                rep = demos.verify(f)
            except (LogFormatError, OSError) as e:
                print(json.dumps({"path": str(f), "error": str(e)}) if args.json else f"error: {e}")
                status = 1
                continue
        info: dict[str, Any] | None = None
        error = None
        try:
            info = demos.inspect(f)
        except (LogFormatError, OSError) as e:
            error = str(e)
        if error is not None or (rep is not None and not rep["ok"]):
            status = 1
        deploy = _deploy_summary(f, info)
        if args.json:
            out = dict(info) if info is not None else {"path": str(f), "error": error}
            if rep is not None:
                out["integrity"] = rep
            if deploy is not None:
                out["deploy"] = deploy
            print(json.dumps(out, sort_keys=True))
            continue
        if info is not None:
            _print_report(info)
            if deploy is not None:
                _print_deploy(deploy)
        elif rep is None or rep["ok"]:  # a sound MCAP file that is not a demo, ...
            print(f"error: {error}")
        else:
            print(f"{f}  ({rep['bytes']} bytes; summary unreadable: {error})")
        if rep is not None:
            _print_integrity(str(f), rep)
    return status
