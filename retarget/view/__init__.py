"""Seeing a run: the human skeleton, the mapped targets and the posed robot arm on one timeline (Rerun), and
pictures without a GUI (matplotlib).  Needs the optional extra ``pip install 'retarget[viz]'``.

- :mod:`~retarget.view.scene`: what to draw, pure numpy (no drawing library): skeleton, placement, workspace;
- :mod:`~retarget.view.columns`: tick records as columns;
- :mod:`~retarget.view.rerun_log`: log a scene and ticks to a Rerun recording;
- :mod:`~retarget.view.live`: a background logger fed by the control loop's ``on_tick`` (bounded queue);
- :mod:`~retarget.view.sinks`: where a recording goes (a file, the browser viewer on loopback, a native viewer);
- :mod:`~retarget.view.plot`: a telemetry CSV as a PNG; :mod:`~retarget.view.sheet`: a contact sheet PNG;
- :mod:`~retarget.view.rig`: a rig's arms at their base poses and the skeleton in its world, pure numpy;
  :mod:`~retarget.view.rig_sheet`: its contact sheet (the Rerun side is in ``rerun_log``).

Only the modules that draw import ``rerun`` or ``matplotlib``, and only when used: :func:`require` checks
for them first and raises one clear error naming the extra.
"""

from __future__ import annotations

import importlib

from retarget.errors import RetargetError

__all__ = ["EXTRA", "ViewUnavailable", "require"]

#: how to install what the views need
EXTRA = "pip install 'retarget[viz]'"


class ViewUnavailable(RetargetError):
    """A view or picture was asked for without the ``viz`` extra installed."""


def require(feature: str, *modules: str) -> None:
    """Raise :class:`ViewUnavailable` (one line naming the extra) unless every module in ``modules`` imports.

    >>> require("a test", "math")
    >>> require("--fly", "no_such_module_xyz")
    Traceback (most recent call last):
    ...
    retarget.view.ViewUnavailable: --fly needs the viz extra: pip install 'retarget[viz]' (no module no_such_module_xyz)
    """
    for name in modules:
        try:
            importlib.import_module(name)
        except ImportError as exc:
            raise ViewUnavailable(f"{feature} needs the viz extra: {EXTRA} (no module {name})") from exc
