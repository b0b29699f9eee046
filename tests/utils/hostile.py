"""Names that try to break out of the files and pages they are written into.

A URDF's ``<robot name>`` and joint names are free text (``&#10;`` in XML is a newline); these
carry URScript statements, spreadsheet formulas, YAML keys and HTML into every place a name
goes. :func:`hostile_urdf` writes a six-joint arm with them (planned with the quintic and the
jerk-limited profile only, which any limits allow).
"""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

#: The robot's name: URScript top-level code, a YAML key, a formula, an HTML payload.
ROBOT_NAME = (
    "arm\npopup(\"pwned\", blocking=True)\nextra_key: injected\r=cmd|' /C calc'!A0"
    "<img src=x onerror=alert(1)>"
)
#: Six joint names: formulas (= + - @), separators (, tab CR LF) and keys.
JOINT_NAMES = (
    "=cmd|' /C calc'!A0",
    "j2\npopup(1)",
    "+j3,@SUM(1+1)*cmd|' /C calc'!A0",
    "-j4\tx",
    "@j5\r",
    "j6\nevil_key: 1",
)
SHOULDER, ELBOW = JOINT_NAMES[1], JOINT_NAMES[2]
_LIMITS = ((-3.0, 3.0), (-1.0, 2.5), (0.0, 2.6), (-3.0, 3.0), (-3.0, 3.0), (-3.0, 3.0))
_AXES = ("0 0 1", "0 1 0", "0 1 0", "0 1 0", "0 0 1", "0 1 0")


def _attr(text: str) -> str:
    return quoteattr(text, {"\n": "&#10;", "\r": "&#13;", "\t": "&#9;"})


def hostile_urdf(robot: str = ROBOT_NAME, joints: tuple[str, ...] = JOINT_NAMES) -> str:
    """A six-joint serial arm (1 kg links) whose names are ``robot`` and ``joints``."""
    links = ["<link name='base'/>"]
    chain = []
    for i, name in enumerate(joints):
        links.append(
            f"<link name='l{i}'><inertial><origin xyz='0 0 -0.1'/><mass value='1.0'/>"
            "<inertia ixx='0.01' iyy='0.01' izz='0.001' ixy='0' ixz='0' iyz='0'/>"
            "</inertial></link>"
        )
        parent = "base" if i == 0 else f"l{i - 1}"
        lo, hi = _LIMITS[i]
        chain.append(
            f"<joint name={_attr(name)} type='revolute'><parent link='{parent}'/>"
            f"<child link='l{i}'/><origin xyz='0 0 -0.2'/><axis xyz='{_AXES[i]}'/>"
            f"<limit lower='{lo}' upper='{hi}' effort='5000' velocity='10'/></joint>"
        )
    body = "\n".join(links + chain)
    return f"<?xml version='1.0'?>\n<robot name={_attr(robot)}>\n{body}\n</robot>\n"
