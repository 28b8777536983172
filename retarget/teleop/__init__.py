"""Teleoperation: move the tool point to targets that arrive while the arm moves.

- :mod:`~retarget.teleop.gate`: parsing and checking target messages (:class:`TargetGate`, :class:`BasePose`);
- :mod:`~retarget.teleop.sources`: where targets come from (one shot, stdin, UDP);
- :mod:`~retarget.teleop.follower`: :class:`Follower` (the tick loop's target source) and :func:`run_teleop`.
"""

from retarget.teleop.follower import Follower, Phase, PoseSolver, TeleopResult, Visit, run_teleop, tool_point
from retarget.teleop.gate import (
    MAX_MESSAGE_BYTES,
    BasePose,
    Message,
    Reject,
    RejectCounter,
    Target,
    TargetBounds,
    TargetGate,
    TargetRejected,
    parse_message,
    step_toward,
)
from retarget.teleop.sources import (
    DEFAULT_UDP_HOST,
    QUEUE_LENGTH,
    OneShotSource,
    Source,
    StdinSource,
    UdpSource,
    is_loopback,
    parse_address,
)

__all__ = [
    "DEFAULT_UDP_HOST",
    "MAX_MESSAGE_BYTES",
    "QUEUE_LENGTH",
    "BasePose",
    "Follower",
    "Message",
    "OneShotSource",
    "Phase",
    "PoseSolver",
    "Reject",
    "RejectCounter",
    "Source",
    "StdinSource",
    "Target",
    "TargetBounds",
    "TargetGate",
    "TargetRejected",
    "TeleopResult",
    "UdpSource",
    "Visit",
    "is_loopback",
    "parse_address",
    "parse_message",
    "run_teleop",
    "step_toward",
    "tool_point",
]
