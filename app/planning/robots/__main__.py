"""Regenerate the shipped URDF/MJCF files and parameter tables.

Run ``python -m app.planning.robots`` after changing a built-in robot's parameters.
"""

from __future__ import annotations

import json

from app.planning.robots._loader import BUILTIN_ROBOTS, ROBOT_DIR, builtin_files, load_robot


def parameters_json(name: str) -> str:
    """The parameter table of a built-in robot (default subject / payload) as JSON text."""
    rows = list(load_robot(name).parameters)
    return json.dumps(rows, indent=1) + "\n"


def main() -> None:
    for name in BUILTIN_ROBOTS:
        urdf, mjcf = builtin_files(name)
        (ROBOT_DIR / f"{name}.urdf").write_text(urdf)
        (ROBOT_DIR / f"{name}.xml").write_text(mjcf)
        (ROBOT_DIR / f"{name}.parameters.json").write_text(parameters_json(name))
        print(f"wrote {ROBOT_DIR / name}.urdf, .xml, .parameters.json")


if __name__ == "__main__":
    main()
