"""Shared fixtures.

The real BVH clips live beside the project in ``../shared/bvh`` and are never
copied into it.  Set ``RETARGET_SHARED_BVH`` to read them from elsewhere.
Tests that need them are skipped, with the reason, when they are absent.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
SHARED_BVH = Path(os.environ.get("RETARGET_SHARED_BVH", REPO.parent / "shared" / "bvh"))


def shared_clips() -> list[Path]:
    """The real clips, sorted by name; empty when the folder is absent."""
    return sorted(SHARED_BVH.glob("*.bvh")) if SHARED_BVH.is_dir() else []


def shared_clip_params() -> list:
    """``shared_clips()`` for ``parametrize``: one skipped case, with the reason, when the folder is absent."""
    clips = shared_clips()
    if clips:
        return [pytest.param(c, id=c.stem) for c in clips]
    reason = f"real BVH clips not found at {SHARED_BVH} (set RETARGET_SHARED_BVH)"
    return [pytest.param(None, id="no-shared-clips", marks=pytest.mark.skip(reason=reason))]


@pytest.fixture
def shared_bvh() -> Path:
    """The folder of real BVH clips; skips the test when it is absent."""
    if not SHARED_BVH.is_dir():
        pytest.skip(f"real BVH clips not found at {SHARED_BVH} (set RETARGET_SHARED_BVH)")
    return SHARED_BVH
