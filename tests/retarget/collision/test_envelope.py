"""The joint envelope behind the folding pairs' nest depths, against the whole chain's forward kinematics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from retarget.arm.load import load_arm
from retarget.collision import CollisionModel
from retarget.collision.distance import segment_segment


@pytest.mark.parametrize("name", ["wx250s", "vx300s", "px100", "koch"])
def test_the_envelope_of_two_capsules_about_their_joint_matches_the_full_kinematics(name):
    model = CollisionModel.for_arm(load_arm(name))
    frames = model._cap_frame
    checked = 0
    for u in range(len(frames)):
        for v in range(len(frames)):
            joint = int(frames[u])
            if frames[v] != joint + 1 or joint == 0:
                continue
            lo, hi = float(model.arm.lower[joint]), float(model.arm.upper[joint])
            Q = np.zeros((max(2, math.ceil((hi - lo) / math.radians(0.5)) + 1), model.arm.n_joints))
            Q[:, joint] = np.linspace(lo, hi, len(Q))
            ends, r = model.capsules(Q)  # every frame, in the base frame: the old, slow way
            d = segment_segment(ends[:, u, 0], ends[:, u, 1], ends[:, v, 0], ends[:, v, 1]) - r[u] - r[v]
            least, most = model._joint_envelope(u, v, joint)
            assert least == pytest.approx(float(d.min()), abs=1e-12)
            assert most == pytest.approx(float(d.max()), abs=1e-12)
            checked += 1
    assert checked
