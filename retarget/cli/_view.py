"""The view options (``--view``, ``--record``, ``--web``, ``--web-port``) of ``view``, ``replay`` and ``teleop``,
and the live view that ``replay``/``teleop`` feed from the loop's ``on_tick``.  ``retarget.view`` (and so
rerun) is imported only when one of them is given; without the ``viz`` extra that is one line and exit 2."""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from retarget.arm import Arm
from retarget.control.loop import tee
from retarget.errors import ConfigError

if TYPE_CHECKING:
    from retarget.bvh.motion import Motion
    from retarget.mapping import Targets
    from retarget.view.live import LiveView
    from retarget.view.sinks import Outputs, WebViewer


def add_view_arguments(parser: argparse.ArgumentParser | Any, *, live: bool) -> None:
    """--view (live commands only), --record RRD, --web, --web-port, --grpc-port (in their own group of a parser)."""
    g = parser.add_argument_group(f"view (needs {_extra()})") if isinstance(parser, argparse.ArgumentParser) else parser
    if live:
        g.add_argument("--view", action="store_true", help="stream the run to a Rerun viewer (native; see --web)")
    g.add_argument("--record", default=None, metavar="RRD", help="save the timeline to a Rerun .rrd file")
    g.add_argument("--web", action="store_true", help="serve the browser viewer on 127.0.0.1 and print its URL")
    g.add_argument("--web-port", default="9090", metavar="PORT", help="the browser viewer's HTTP port (default 9090)")
    g.add_argument("--grpc-port", default="9876", metavar="PORT", help="the recording's gRPC port for --web (9876)")


def _extra() -> str:
    from retarget.view import EXTRA

    return EXTRA


def wants_view(args: argparse.Namespace) -> bool:
    return bool(getattr(args, "view", False) or args.record is not None or args.web)


def check_view_options(args: argparse.Namespace) -> None:
    """Before any work: the view options' values, and the extra they need (one line, exit 2, without it)."""
    if wants_view(args):
        outputs(args, spawn=False)


def outputs(args: argparse.Namespace, *, spawn: bool) -> Outputs:
    """The :class:`~retarget.view.sinks.Outputs` the options ask for (checks first that the extra is installed, and
    for a native viewer that there is a display, before anything is solved)."""
    from retarget.view import require

    flag = "--record" if args.record is not None else "--web" if args.web else "--view"
    require(flag, "rerun")
    from retarget.view.sinks import Outputs, require_display

    out = Outputs(
        record=None if args.record is None else Path(args.record),
        web=args.web,
        web_port=_port(args.web_port, "--web-port"),
        grpc_port=_port(args.grpc_port, "--grpc-port"),
        spawn=spawn and not args.web and args.record is None,
    )
    if out.spawn:
        require_display()
    return out


def _port(text: str, option: str) -> int:
    try:
        port = int(text)
    except ValueError:
        raise ConfigError("Expected a TCP port number", key=option, value=text) from None
    if not 1 <= port <= 65535:
        raise ConfigError("Expected a TCP port from 1 to 65535", key=option, value=port)
    return port


@contextmanager
def live_view(
    args: argparse.Namespace, arm: Arm, *, motion: Motion | None = None, targets: Targets | None = None, name: str
) -> Iterator[LiveView | None]:
    """A started :class:`~retarget.view.live.LiveView` when the view options ask for one (else None); closed
    (queue drained, recording flushed) on exit.  With ``--web`` the viewer's server starts first and stays up
    after: :func:`serve_web` keeps it until Ctrl-C (it is stopped at exit in any case)."""
    if not wants_view(args):
        yield None
        return
    out = outputs(args, spawn=True)
    from retarget.view.live import LiveView
    from retarget.view.scene import Layout, Scene
    from retarget.view.sinks import open_recording

    if motion is not None and targets is not None:
        scene = Scene.for_clip(motion, arm, targets, layout=Layout(getattr(args, "layout", "side")))
    else:
        scene = Scene.for_arm(arm)
    web = start_web(out)
    _SERVING.extend([web] if web is not None else [])
    with ExitStack() as stack:
        rec = stack.enter_context(open_recording(scene, out, name=name, web=web))
        live = stack.enter_context(LiveView(rec, scene))
        yield live


#: the --web servers :func:`live_view` started, for :func:`serve_web` after the run
_SERVING: list[WebViewer] = []


def start_web(out: Outputs, files: tuple[Path, ...] = ()) -> WebViewer | None:
    """The started :class:`~retarget.view.sinks.WebViewer` when ``--web`` is given (else None)."""
    if not out.web:
        return None
    from retarget.view.sinks import WebViewer

    return WebViewer(web_port=out.web_port, grpc_port=out.grpc_port, files=files).start()


def serve_web(args: argparse.Namespace) -> None:
    """After a run with ``--web``: keep the viewer up until Ctrl-C (then KeyboardInterrupt: exit 130)."""
    while _SERVING:
        serve_until_interrupted(_SERVING.pop())


def serve_until_interrupted(web: WebViewer) -> None:
    """Keep ``web`` up until Ctrl-C (KeyboardInterrupt), SIGTERM or SIGHUP (:class:`SignalInterrupt`), which
    propagate after the server is stopped: ``retarget.cli.main`` turns them into exit 130, 143, 129."""
    import signal
    import sys

    from retarget.cli._bus import SignalInterrupt

    def interrupt(signum: int, frame: Any) -> None:
        raise SignalInterrupt(signum)

    print(f"retarget: serving the viewer at {web.url} ; Ctrl-C to stop", file=sys.stderr, flush=True)
    previous = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        for s in previous:
            signal.signal(s, interrupt)
        web.wait()
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        web.close()


def forward(*, on_tick: Any, live: LiveView | None) -> Any:
    """``on_tick`` followed by ``live`` (either may be None)."""
    if live is None:
        return on_tick
    return tee(on_tick, live)
