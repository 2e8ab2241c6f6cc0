#!/usr/bin/env python3
"""Write robots/arash_asist.urdf, the reconstructed ARASH:ASiST model.

The numbers below are a reconstruction from the published description (see docs/robot.md), not the
manufacturer's CAD. Inertias come from solid boxes so that every body is physically consistent by
construction. Run from the repository root: python3 robots/make_arash_asist.py
"""

from pathlib import Path

# Geometry of the parallelogram in the yoke frame (m). The RCM is the yoke frame's origin.
PIVOT_A = (0.0, 0.14, 0.0)  # actuated rocker pivot on the yoke
PIVOT_B = (0.0, 0.07, 0.0)  # passive rocker pivot: A + (coupler vector) / 2
ROCKER_LENGTH = 0.16
COUPLER = (0.0, -0.14, 0.0)  # from the top of rocker A to the holder pivot; equals -A, so A + c = RCM
HOLDER_TO_CARRIAGE = 0.08  # along the instrument axis, at d = 0
CW_OFFSET_X = 0.035  # counterweights sit either side of pivot A
RCM_HEIGHT = 0.25  # RCM above the base frame

DEG = 3.141592653589793 / 180.0


def box_inertia(m, sx, sy, sz):
    return (m * (sy**2 + sz**2) / 12, m * (sx**2 + sz**2) / 12, m * (sx**2 + sy**2) / 12)


# name: (mass kg, centre of mass in the link frame m, box size m)
BODIES = {
    "yaw_yoke": (0.40, (0.0, 0.08, 0.06), (0.06, 0.20, 0.16)),
    "rocker_a": (0.10, (0.0, 0.0, 0.08), (0.015, 0.015, 0.17)),
    "rocker_b": (0.08, (0.0, 0.0, 0.08), (0.012, 0.012, 0.17)),
    "coupler": (0.12, (0.0, -0.07, 0.0), (0.015, 0.16, 0.015)),
    "instrument_holder": (0.18, (0.0, 0.0, -0.04), (0.03, 0.03, 0.14)),
    "insertion_carriage": (0.10, (0.0, 0.012, -0.03), (0.02, 0.03, 0.10)),
    "counterweight_left": (0.14, (0.0, 0.01, -0.06), (0.03, 0.04, 0.04)),
    "counterweight_right": (0.14, (0.0, 0.01, -0.06), (0.03, 0.04, 0.04)),
}

# CAD friction guesses for the actuated joints: (viscous, Coulomb) in N·m·s/rad and N·m, or N·s/m and N.
FRICTION = {"yaw": (0.005, 0.01), "pitch": (0.005, 0.01), "insertion": (2.0, 0.3)}

# (joint, type, parent, child, origin xyz, axis, limits or None, mimic or None)
JOINTS = [
    ("yaw", "revolute", "base", "yaw_yoke", (0, 0, RCM_HEIGHT), (0, 0, 1), (-42.5 * DEG, 42.5 * DEG, 200 * DEG), None),
    ("pitch", "revolute", "yaw_yoke", "rocker_a", PIVOT_A, (1, 0, 0), (-25 * DEG, 55 * DEG, 200 * DEG), None),
    ("rocker_b_pivot", "revolute", "yaw_yoke", "rocker_b", PIVOT_B, (1, 0, 0), None, ("pitch", 1.0, 0.0)),
    ("coupler_pivot", "revolute", "rocker_a", "coupler", (0, 0, ROCKER_LENGTH), (1, 0, 0), None, ("pitch", -1.0, 0.0)),
    ("holder_pivot", "revolute", "coupler", "instrument_holder", COUPLER, (1, 0, 0), None, ("pitch", 1.0, 0.0)),
    ("insertion", "prismatic", "instrument_holder", "insertion_carriage", (0, 0, -HOLDER_TO_CARRIAGE), (0, 0, -1),
     (-0.014, 0.027, 0.100), None),
    ("counterweight_left_pivot", "revolute", "yaw_yoke", "counterweight_left", (-CW_OFFSET_X,) + PIVOT_A[1:], (1, 0, 0),
     None, ("pitch", 1.0, 0.0)),
    ("counterweight_right_pivot", "revolute", "yaw_yoke", "counterweight_right", (CW_OFFSET_X,) + PIVOT_A[1:],
     (1, 0, 0), None, ("pitch", 1.0, 0.0)),
]

# Named frames without mass, on fixed joints: (frame, parent link, origin xyz, rpy). The instrument's tip
# is on its axis, one holder-to-carriage length beyond the carriage, so at d = 0 it is at the RCM and d is
# how far it has passed it; its z axis points along the instrument, into the eye.
FRAMES = [
    ("instrument_tip", "insertion_carriage", (0, 0, -HOLDER_TO_CARRIAGE), (3.141592653589793, 0, 0)),
    ("remote_centre", "yaw_yoke", (0, 0, 0), (0, 0, 0)),
]


def fmt(v):
    return " ".join(f"{x:.10g}" for x in v)


def link_xml(name):
    m, com, size = BODIES[name]
    ixx, iyy, izz = box_inertia(m, *size)
    return f"""  <link name="{name}">
    <inertial>
      <origin xyz="{fmt(com)}" rpy="0 0 0"/>
      <mass value="{m:.10g}"/>
      <inertia ixx="{ixx:.10g}" ixy="0" ixz="0" iyy="{iyy:.10g}" iyz="0" izz="{izz:.10g}"/>
    </inertial>
  </link>
"""


def joint_xml(name, kind, parent, child, xyz, axis, limits, mimic):
    lines = [f'  <joint name="{name}" type="{kind}">',
             f'    <parent link="{parent}"/>',
             f'    <child link="{child}"/>',
             f'    <origin xyz="{fmt(xyz)}" rpy="0 0 0"/>',
             f'    <axis xyz="{fmt(axis)}"/>']
    if limits is not None:
        lo, hi, vel = limits
        lines.append(f'    <limit lower="{lo:.10g}" upper="{hi:.10g}" velocity="{vel:.10g}" effort="5"/>')
    else:
        lines.append('    <limit lower="-3.14159" upper="3.14159" velocity="10" effort="5"/>')
    if name in FRICTION:
        fv, fc = FRICTION[name]
        lines.append(f'    <dynamics damping="{fv:.10g}" friction="{fc:.10g}"/>')
    if mimic is not None:
        j, mult, off = mimic
        lines.append(f'    <mimic joint="{j}" multiplier="{mult:.10g}" offset="{off:.10g}"/>')
    lines.append("  </joint>\n")
    return "\n".join(lines)


def frame_xml(name, parent, xyz, rpy):
    return f"""  <link name="{name}"/>
  <joint name="{name}_mount" type="fixed">
    <parent link="{parent}"/>
    <child link="{name}"/>
    <origin xyz="{fmt(xyz)}" rpy="{fmt(rpy)}"/>
  </joint>
"""


def main():
    out = ['<?xml version="1.0"?>',
           "<!-- Generated by robots/make_arash_asist.py. A reconstruction of ARASH:ASiST; see docs/robot.md. -->",
           '<robot name="arash_asist">',
           '  <link name="base"/>']
    out += [link_xml(n) for n in BODIES]
    out += [joint_xml(*j) for j in JOINTS]
    out += [frame_xml(*f) for f in FRAMES]
    out.append("</robot>\n")
    path = Path(__file__).with_name("arash_asist.urdf")
    path.write_text("\n".join(out))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
