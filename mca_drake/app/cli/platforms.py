"""`mca-drake platforms`: the packaged motion platforms, or one platform file, described.

The table gives each platform's name, kind, joint count and joints (revolute in rad,
prismatic in m) with their limits; `--json` prints a list of objects with at least `name`,
`kind` and `dof`. Runs without Drake (the URDF is then read with the XML reader).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from mca_drake.platforms.files import load_platform, packaged_platforms, read_platform_file
from mca_drake.platforms.files import platform_file as find_platform_file


def add_parser(commands) -> None:
    """Registers `platforms` on the `mca-drake` sub-command parser."""
    parser = commands.add_parser(
        "platforms",
        help="list the packaged motion platforms (or describe one platform file)",
        description=(
            "List the packaged motion platforms: name, kind, joints and their limits. "
            "Any command's --platform takes one of these names or a platform file."
        ),
    )
    parser.add_argument(
        "platform",
        nargs="?",
        default=None,
        help="a packaged name or a platform file to describe (default: every packaged one)",
    )
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.set_defaults(func=run_platforms)


def platform_records(names_or_files: list[str]) -> list[dict]:
    """One JSON-ready description per platform: name, kind, dof, joints with limits, home,
    the file and the sources it states."""
    records = []
    for name_or_file in names_or_files:
        path = find_platform_file(name_or_file)
        robot = load_platform(path)
        joints = [
            {
                "name": name,
                "kind": kind,
                "unit": "m" if kind == "prismatic" else "rad",
                "position": [float(lo), float(hi)],
                "velocity": float(v),
                "acceleration": float(a),
            }
            for name, kind, lo, hi, v, a in zip(
                robot.joint_names,
                robot.joint_kinds,
                robot.q_min,
                robot.q_max,
                robot.qd_max,
                robot.qdd_max,
                strict=True,
            )
        ]
        records.append(
            {
                **robot.summary(),
                "joints": joints,
                "home": robot.home.tolist(),
                "head_frame": robot.head_frame,
                "file": str(path),
                "urdf": str(robot.urdf_path),
                "source": read_platform_file(path).source,
            }
        )
    return records


def format_platforms(records: list[dict]) -> str:
    """The records of `platform_records` as a readable table per platform."""
    lines = []
    for record in records:
        lines.append(
            f"{record['name']}: {record['kind']}, {record['dof']} joints ({record['file']})"
        )
        if record["source"]:
            lines.append(f"  source: {record['source']}")
        lines.append(f"  {'joint':<12}{'kind':<11}{'range':>22}{'velocity':>11}{'accel.':>9}")
        for joint in record["joints"]:
            lo, hi = joint["position"]
            unit = joint["unit"]
            lines.append(
                f"  {joint['name']:<12}{joint['kind']:<11}"
                f"{f'{lo:.3f} .. {hi:.3f} {unit}':>22}{joint['velocity']:>9.3f}/s"
                f"{joint['acceleration']:>7.3f}/s2"
            )
        actuators = record.get("actuators")
        if actuators:  # a legged platform: its coordinates' box is each one's reach alone
            unit = actuators["unit"]
            lines.append(
                f"  {len(actuators['names'])} {actuators['kind']} actuators: "
                f"{actuators['min_position']:.3f} .. {actuators['max_position']:.3f} {unit}, "
                f"{actuators['max_speed']:.3f} {unit}/s, "
                f"{actuators['max_acceleration']:.3f} {unit}/s2 (the joints' ranges are each "
                "one's reach alone from home; the clamp holds the legs)"
            )
        lines.append("")
    return "\n".join(lines).rstrip("\n")


def run_platforms(args: argparse.Namespace) -> int:
    names = [args.platform] if args.platform else list(packaged_platforms())
    records = platform_records(names)
    if args.json:
        print(json.dumps(records, indent=2, default=lambda v: np.asarray(v).tolist()))
    else:
        print(format_platforms(records))
    return 0
