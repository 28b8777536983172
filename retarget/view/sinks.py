"""Where a recording goes: an ``.rrd`` file, the browser viewer served on loopback, or a native viewer.

    with WebViewer(web_port=9090, grpc_port=9876) as web:   # only for --web
        with open_recording(scene, outputs, web=web) as rec:
            log_ticks(rec, scene, columns)
        web.wait()                                      # until Ctrl-C

The browser viewer is Rerun's own server (the ``rerun`` program that rerun-sdk ships) run as a child process
bound to 127.0.0.1: ``rerun --serve-web --bind 127.0.0.1`` hosts the viewer's files on ``web_port`` and a gRPC
proxy on ``grpc_port`` that buffers what the SDK logs to it (and any ``.rrd`` files given) for viewers that come
later.  Not ``rr.serve_web_viewer``: in rerun-sdk 0.41 its HTTP server listens on 0.0.0.0 with no way to say
otherwise (its signature has no address), and a driver's view has no business on the network.
"""

from __future__ import annotations

import atexit
import importlib.util
import logging
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import IO

import rerun as rr

from retarget.errors import ConfigError
from retarget.view.rerun_log import blueprint, log_rig_scene, log_scene, rig_blueprint
from retarget.view.rig import RigScene
from retarget.view.scene import Scene

__all__ = ["Outputs", "WebViewer", "open_recording", "rerun_program", "web_url"]

log = logging.getLogger(__name__)

LOOPBACK = "127.0.0.1"
START_TIMEOUT_S = 15.0  #: the server's ports must accept connections within this


@dataclass(frozen=True, kw_only=True)
class Outputs:
    """Where to send a recording: any of a file, the browser viewer, a native viewer (``spawn``)."""

    record: Path | None = None
    web: bool = False
    web_port: int = 9090
    grpc_port: int = 9876
    spawn: bool = False

    @property
    def any(self) -> bool:
        return self.record is not None or self.web or self.spawn


def rerun_program() -> str:
    """The path of the ``rerun`` program that rerun-sdk ships (``RERUN_CLI_PATH`` overrides it, as in rerun_cli)."""
    if "RERUN_CLI_PATH" in os.environ:
        return os.environ["RERUN_CLI_PATH"]
    spec = importlib.util.find_spec("rerun_cli")
    folder = Path(spec.origin).parent if spec is not None and spec.origin else Path("rerun_cli")
    bundled = folder / ("rerun.exe" if sys.platform.startswith("win") else "rerun")
    found = str(bundled) if bundled.is_file() else shutil.which("rerun")
    if found is None:
        raise ConfigError(f"Expected the rerun program of rerun-sdk at {bundled}", key="--web", value=True)
    return found


class WebViewer:
    """Rerun's server on 127.0.0.1 as a child process: the browser viewer's files on ``web_port``, a gRPC proxy
    on ``grpc_port`` (it keeps what is logged to it, and ``files``, for viewers that connect later).  A context
    manager: started on entry, stopped (SIGTERM, then SIGKILL) on exit and at the latest when Python exits.

    >>> WebViewer(web_port=8080, grpc_port=8081).url
    'http://127.0.0.1:8080/?url=rerun%2Bhttp://127.0.0.1:8081/proxy'
    """

    def __init__(self, *, web_port: int = 9090, grpc_port: int = 9876, files: Sequence[Path] = ()) -> None:
        self.web_port, self.grpc_port, self.files = web_port, grpc_port, tuple(files)
        self.process: subprocess.Popen[bytes] | None = None
        self._log: IO[bytes] | None = None

    @property
    def grpc_url(self) -> str:
        """Where the SDK sends and the viewer reads: ``rerun+http://127.0.0.1:<grpc_port>/proxy``."""
        return f"rerun+http://{LOOPBACK}:{self.grpc_port}/proxy"

    @property
    def url(self) -> str:
        """The address to open in a browser."""
        return web_url(self.grpc_url, self.web_port)

    def start(self) -> WebViewer:
        for port, option in ((self.web_port, "--web-port"), (self.grpc_port, "--grpc-port")):
            _check_free(port, option)
        argv = [rerun_program(), "--serve-web", "--bind", LOOPBACK, "--web-viewer-port", str(self.web_port),
                "--port", str(self.grpc_port), *(str(f) for f in self.files)]  # fmt: skip
        self._log = tempfile.TemporaryFile()
        # its own session: the Ctrl-C that stops a run reaches us only, the viewer stays up until we end it
        self.process = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=self._log, stderr=subprocess.STDOUT,
                                        start_new_session=True)  # fmt: skip
        atexit.register(self.close)
        try:
            self._wait_listening()
        except BaseException:
            self.close()
            raise
        log.info("rerun server pid %d on %s, viewer on port %d", self.process.pid, self.grpc_url, self.web_port)
        return self

    def _wait_listening(self) -> None:
        assert self.process is not None
        deadline = time.monotonic() + START_TIMEOUT_S
        waiting = [self.web_port, self.grpc_port]
        while waiting:
            if self.process.poll() is not None:
                raise ConfigError(f"Expected the Rerun server to start, it exited with {self.process.returncode}: "
                                  f"{self._last_line()}", key="--web", value=True)  # fmt: skip
            if time.monotonic() > deadline:
                raise ConfigError(f"Expected the Rerun server to listen within {START_TIMEOUT_S:.0f} s",
                                  key="--web", value=True)  # fmt: skip
            with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
                if probe.connect_ex((LOOPBACK, waiting[0])) == 0:
                    waiting.pop(0)
                    continue
            time.sleep(0.05)

    def _last_line(self) -> str:
        if self._log is None:
            return ""
        self._log.seek(0)
        text = re.sub(r"\x1b\[[0-9;]*m", "", self._log.read().decode(errors="replace"))  # its colours
        lines = [line for line in text.splitlines() if line.strip()]
        return lines[-1][-200:] if lines else "(no output)"

    def close(self) -> None:
        """Stop the server (idempotent)."""
        process, self.process = self.process, None
        if process is not None and process.poll() is None:
            process.terminate()
            try:
                process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        if self._log is not None:
            self._log.close()
            self._log = None
        atexit.unregister(self.close)

    def wait(self) -> None:
        """Block while the server runs (until a KeyboardInterrupt, say); ConfigError if it exits by itself."""
        while self.process is not None and self.process.poll() is None:
            time.sleep(0.2)
        if self.process is not None:
            raise ConfigError(f"Expected the Rerun server to keep running, it exited: {self._last_line()}",
                              key="--web", value=True)  # fmt: skip

    def __enter__(self) -> WebViewer:
        return self.start()

    def __exit__(self, *exc: type[BaseException] | BaseException | TracebackType | None) -> None:
        self.close()


def _check_free(port: int, option: str) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((LOOPBACK, port))
        except OSError as exc:
            raise ConfigError(f"Expected a free TCP port on {LOOPBACK} ({exc.strerror})", key=option,
                              value=port) from None  # fmt: skip


@contextmanager
def open_recording(
    scene: Scene | RigScene, outputs: Outputs, *, name: str = "retarget", web: WebViewer | None = None
) -> Iterator[rr.RecordingStream]:
    """A recording stream with the scene's (one arm's, or a rig's) static part logged, sent to ``outputs``;
    flushed and closed after.

    ``web``: a started :class:`WebViewer` to stream to (its URL goes to stderr).
    ``spawn``: a native viewer (needs a display; the error says to use ``--web`` or ``--record`` instead).
    """
    rec = rr.RecordingStream("retarget", recording_id=uuid.uuid4())
    layout = rig_blueprint(scene) if isinstance(scene, RigScene) else blueprint(scene)
    sinks: list[object] = []
    if outputs.record is not None:
        sinks.append(rr.FileSink(outputs.record))
    if web is not None:
        sinks.append(rr.GrpcSink(web.grpc_url))
    if sinks:
        rec.set_sinks(*sinks, default_blueprint=layout)  # type: ignore[arg-type]
    if outputs.spawn:
        require_display()
        try:
            rr.spawn(recording=rec, default_blueprint=layout, hide_welcome_screen=True)
        except Exception as exc:  # no display, no viewer binary
            raise ConfigError(f"Expected a native Rerun viewer to open ({exc}); use --web or --record", key="--view",
                              value=True) from exc  # fmt: skip
    rec.send_recording_name(name)
    if isinstance(scene, RigScene):
        log_rig_scene(rec, scene)
    else:
        log_scene(rec, scene)
    if web is not None:
        print(f"retarget: viewer at {web.url}", file=sys.stderr, flush=True)
    try:
        yield rec
    finally:
        rec.flush()
        rec.disconnect()


def require_display(environ: dict[str, str] | None = None, platform: str = sys.platform) -> None:
    """Raise :class:`ConfigError` when a native viewer cannot show: on Linux and the BSDs, neither ``DISPLAY`` nor
    ``WAYLAND_DISPLAY`` set in ``environ`` (default ``os.environ``).  Without this, the viewer process dies at
    once and the recording waits for it forever; elsewhere (macOS, Windows) there is always a display.

    >>> require_display({"DISPLAY": ":0"}, "linux")
    >>> require_display({}, "darwin")
    >>> require_display({}, "linux")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    retarget.errors.ConfigError: --view: Expected a display for a native Rerun viewer (...); use --png, --web or ...
    """
    env = os.environ if environ is None else environ
    if platform.startswith(("linux", "freebsd", "openbsd", "netbsd")) and not (
        env.get("DISPLAY") or env.get("WAYLAND_DISPLAY")
    ):
        raise ConfigError("Expected a display for a native Rerun viewer (DISPLAY and WAYLAND_DISPLAY are unset); "
                          "use --png, --web or --record", key="--view", value=True)  # fmt: skip


def web_url(grpc_uri: str, web_port: int) -> str:
    """The browser URL of the web viewer on loopback, connected to the gRPC server at ``grpc_uri``.

    >>> web_url("rerun+http://127.0.0.1:9876/proxy", 9090)
    'http://127.0.0.1:9090/?url=rerun%2Bhttp://127.0.0.1:9876/proxy'
    """
    return f"http://{LOOPBACK}:{web_port}/?url={grpc_uri.replace('+', '%2B')}"
