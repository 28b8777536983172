"""Inverse kinematics: the closed-form CCD solver with joint-limit clamping, an early-out and a sweep budget.

- :mod:`~retarget.ik.ccd`: :class:`CCDSolver`, :func:`solve_ik`, :class:`IKResult`, the joint weights.
"""

from retarget.ik.ccd import CCDSolver, IKResult, SweepOrder, Weighting, joint_weights, solve_ik

__all__ = ["CCDSolver", "IKResult", "SweepOrder", "Weighting", "joint_weights", "solve_ik"]
