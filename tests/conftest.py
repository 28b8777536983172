"""Shared fixtures.

The real BVH clips live beside the project in ``../shared/bvh`` and are never
copied into it.  Set ``RETARGET_SHARED_BVH`` to read them from elsewhere.
Tests that need them are skipped, with the reason, when they are absent.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import dynamixel_sdk.port_handler
import pytest

from tests.helpers import SHARED_BVH

#: The SDK waits ``2 * LATENCY_TIMER + 2`` ms for a reply.  A real servo answers within microseconds, but a
#: simulated one on a pty is a thread or process of this test run: on a loaded 2-core CI machine it can be
#: descheduled past the SDK's stock 34 ms and turn a reply into COMM_RX_TIMEOUT.
TEST_LATENCY_TIMER_MS = 100


@pytest.fixture(autouse=True, scope="session")
def _no_user_calibration(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """Point the user configuration folder (``retarget calibrate``'s default, applied automatically by replay,
    teleop and scan) at an empty folder, so a developer's own saved calibration never changes a test."""
    saved = {name: os.environ.get(name) for name in ("XDG_CONFIG_HOME", "APPDATA")}
    empty = str(tmp_path_factory.mktemp("config"))
    os.environ.update(XDG_CONFIG_HOME=empty, APPDATA=empty)
    yield
    for name, value in saved.items():
        if value is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = value


@pytest.fixture
def patient_sdk(monkeypatch: pytest.MonkeyPatch) -> None:
    """Give the plain SDK the reply window it would have on a high-latency adapter (200 ms).

    Users raise ``LATENCY_TIMER`` the same way (DynamixelSDK#288); the PortHandler class stays unchanged.
    Tests that expect silence wait this long per missed reply.
    """
    monkeypatch.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER", TEST_LATENCY_TIMER_MS)


@pytest.fixture
def shared_bvh() -> Path:
    """The folder of real BVH clips; skips the test when it is absent."""
    if not SHARED_BVH.is_dir():
        pytest.skip(f"real BVH clips not found at {SHARED_BVH} (set RETARGET_SHARED_BVH)")
    return SHARED_BVH
