"""The Koch's collision capsules (config/arms/koch.toml ``[collision]``) enclose its parts, and tightly where the arm
works: below a level gripper, and between the gripper and the forearm."""

from __future__ import annotations

import numpy as np
import pytest

from retarget import load_arm
from retarget.collision import Capsule, CollisionModel

#: mm, in each link's frame: of the parts the arm file's capsules enclose, the vertices farthest along the 26
#: directions (+-x, +-y, +-z and their diagonals) and, per capsule, the three farthest from its axis (they set its
#: radius) and the three nearest its surface among those no other capsule holds: any capsule shrunk by 1 mm fails
#: (jaw2 by 1.2 mm, jaw1 by 3: the part only they hold lies that deep inside them).
#: From s1lent4gnt/koch-v1-1 @ cc1a4eb simulation/meshes (Apache-2.0, (c) 2024 The Hugging Face team):
#: link_2{,_motor}, link_3{,_motor}, link_4{,_motor}, and link_5{,_motor} with link_6 (the jaw) turned about -z
#: through (-13.15, -7.5, 14.5) mm over the gripper's range -1.60..0.032 rad.
# fmt: off
EXTREMES = {
    "shoulder_lift": [
        (-24.3, 9.6, 117.3), (-24.3, 32.2, 117.3), (-24.1, 9.4, 117.2), (-22.8, 6.7, 108.3), (-22.6, 35.4, 108.3),
        (-8.4, -1.1, -10.0), (-8.4, 42.9, -10.0), (-5.1, -1.1, -11.9), (-1.5, -1.1, -12.9), (-1.5, 42.9, -12.9),
        (-0.6, -1.1, -9.0), (2.0, 6.2, 119.0), (2.0, 35.6, 119.0), (2.3, -1.1, -12.8), (2.3, 42.9, -12.8),
        (13.0, -1.1, 35.0), (13.0, 0.7, 42.5), (13.0, 6.2, 119.0), (13.0, 35.6, 119.0), (13.0, 42.9, -0.0),
        (13.0, 42.9, 35.0),
    ],
    "elbow_flex": [
        (-110.0, 3.1, -6.3), (-110.0, 4.6, 0.2), (-110.0, 8.0, -6.3), (-110.0, 25.7, -6.3), (-109.0, 3.2, 12.7),
        (-109.0, 8.0, 12.7), (-109.0, 25.8, 12.7), (-108.3, 0.0, 3.2), (-108.3, 29.0, 2.7), (-39.3, -1.9, 14.5),
        (-18.4, -2.9, 14.5), (-18.4, 31.8, 14.5), (-14.0, 4.5, -8.5), (-8.7, -3.1, 11.6), (1.4, -3.1, -8.5),
        (1.4, -0.1, -8.5), (1.4, 32.0, -8.5), (5.1, -3.0, 7.0), (5.1, -0.1, 7.0), (5.1, 32.0, 7.0), (7.9, 32.0, 2.5),
        (8.4, -3.0, 1.0), (8.4, -0.1, 1.0), (8.4, 32.0, 1.0),
    ],
    "wrist_flex": [
        (-45.0, 5.3, -0.0), (-45.0, 12.8, -7.8), (-45.0, 12.8, 7.8), (-42.0, 37.4, -8.9), (-41.8, 3.6, -9.0),
        (-41.8, 4.6, 10.0), (-41.8, 37.6, -9.0), (-41.8, 37.6, 9.0), (-19.0, -3.3, -11.0), (-19.0, -3.3, 11.0),
        (-19.0, 38.7, -11.0), (-19.0, 38.7, 11.0), (-16.0, -3.3, 11.0), (-16.0, 15.6, -11.0), (-16.0, 38.7, 11.0),
        (0.0, -3.3, 4.8), (6.7, -3.3, -6.1), (6.7, -3.3, 6.0), (6.7, 32.2, -6.1), (6.7, 32.2, 6.0),
        (9.0, -3.3, -0.0), (9.0, -0.3, -0.0), (9.0, 32.2, -0.0),
    ],
    "wrist_roll": [
        (-70.4, -7.0, 0.6), (-69.3, -8.2, -2.5), (-69.3, -8.2, 3.7), (-67.2, 15.0, -3.1), (-65.7, 16.2, 5.2),
        (-65.5, 16.3, -4.2), (-53.8, -47.8, 0.2), (-53.8, -47.8, 0.6), (-53.2, -46.9, -2.5), (-53.2, -46.9, 3.7),
        (-53.0, -48.0, 0.6), (-52.0, -49.5, 0.6), (-33.1, -0.4, -17.6), (-32.0, 9.2, 14.8), (-32.0, 20.2, -14.8),
        (-32.0, 20.2, 14.7), (-31.8, -0.3, -17.7), (-29.0, -8.2, -17.7), (-27.5, -0.6, -17.7), (-27.1, 0.1, -17.7),
        (-26.4, -16.3, -17.7), (-24.7, -63.6, 0.6), (-24.7, -62.5, 3.7), (-24.7, -62.4, -2.5), (-18.7, -31.3, 17.8),
        (-18.5, -19.4, -17.7), (-18.5, -19.4, 17.8), (-17.8, -60.9, -3.6), (-15.2, -57.7, -4.9), (-15.2, -57.7, 6.1),
        (-13.5, 0.8, -17.7), (-13.3, -2.7, 17.8), (-11.5, -20.5, -17.7), (-6.2, -30.9, 17.8), (-5.6, -30.9, 17.7),
        (-5.6, -30.7, 17.8), (-0.0, -17.5, -14.7), (0.0, 1.2, -6.0), (0.0, 20.2, -14.8), (-0.0, 20.2, 14.8),
    ],
}
# fmt: on


@pytest.fixture(scope="module")
def koch():
    return load_arm("koch")


def capsules_on(arm, frame: str) -> list[Capsule]:
    index = 1 + arm.joint_names.index(frame)  # a joint's child frame
    return [link.shape for link in arm.geometry.links if link.frame == index and isinstance(link.shape, Capsule)]


def inside(capsule: Capsule, p: np.ndarray) -> bool:
    a, b = np.asarray(capsule.a), np.asarray(capsule.b)
    t = np.clip((p - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-18), 0.0, 1.0)
    return bool(np.linalg.norm(p - (a + t * (b - a))) <= capsule.radius)


@pytest.mark.parametrize("frame", list(EXTREMES))
def test_the_capsules_of_each_koch_link_hold_its_mesh_extremes(koch, frame):
    capsules = capsules_on(koch, frame)
    outside = [p for p in EXTREMES[frame] if not any(inside(c, np.array(p) / 1000) for c in capsules)]
    assert capsules and not outside


def test_a_level_gripper_reaches_little_farther_below_its_tool_point_than_its_parts(koch):
    model = CollisionModel.for_arm(koch)
    q = np.zeros(koch.n_joints)  # home: the gripper level, not rolled
    ends, radii = model.capsules(q)  # every capsule's ends (n, 2, 3) and radius, base frame
    roll = 1 + koch.joint_names.index("wrist_roll")
    capsule_links = [link for link in model.geometry.links if isinstance(link.shape, Capsule)]  # in that order
    lowest = min(float(ends[k, :, 2].min() - radii[k]) for k, link in enumerate(capsule_links) if link.frame == roll)
    tool = koch.fk(q)[0][2, 3]
    parts = 0.0145 + 0.0177  # the tool point (the jaw's pivot) 14.5 mm above the link_5 origin, the jaw 17.7 below
    assert parts < tool - lowest < parts + 0.006  # 37 mm; 64 mm with one capsule round the jaw's whole sweep


def test_the_koch_at_home_and_rest_keeps_the_clearance_with_room_and_nothing_nested(koch):
    model = CollisionModel.for_arm(koch)
    assert model.geometry.nest == ()  # the gripper and jaw capsules were nested into the forearm's at the zero pose
    for q in (koch.home, koch.rest):
        assert model.min_clearance(q) >= model.clearance + 0.01, model.worst_pair(q)
