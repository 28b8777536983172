"""``--web``: Rerun's server on 127.0.0.1 only, Ctrl-C ends it (exit 130, no traceback, the ports closed), and a
real browser (headless Chromium, when installed) shows the served recording: the arm and the driving human arm
drawn in their colours.  Nothing leaves the machine: the server runs with ``CI`` set (Rerun's analytics are off
on CI), Chromium resolves every host but 127.0.0.1 to nothing."""

from __future__ import annotations

import base64
import fcntl
import io
import json
import os
import select
import shutil
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from retarget.cli import main

pytest.importorskip("rerun", reason="the viz extra (rerun-sdk) is not installed")
image = pytest.importorskip("matplotlib.image", reason="the viz extra (matplotlib) is not installed")

ENV = {**os.environ, "CI": "1"}  # re_analytics: "Analytics disabled on CI" (crates/utils/re_analytics pipeline.rs)
ROBOT, CHAIN = (40, 110, 220), (255, 140, 0)  # retarget.view.rerun_log's robot and driving-arm colours
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def free_ports(n: int) -> list[int]:
    socks = [socket.socket() for _ in range(n)]
    for s in socks:
        s.bind(("127.0.0.1", 0))
    ports = [s.getsockname()[1] for s in socks]
    for s in socks:
        s.close()
    return ports


def listening(port: int) -> list[str]:
    """The local addresses (hex, as /proc/net/tcp{,6} writes them) listening on ``port``."""
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with open(table) as f:
            for line in f.readlines()[1:]:
                local, state = line.split()[1], line.split()[3]
                if state == "0A" and int(local.rsplit(":", 1)[1], 16) == port:
                    found.append(local.rsplit(":", 1)[0])
    return found


class Served:
    """``retarget <argv> --web`` as a child process, up once it says "Ctrl-C to stop"."""

    def __init__(self, *argv: str, cwd) -> None:
        self.web_port, self.grpc_port = free_ports(2)
        ports = ["--web-port", str(self.web_port), "--grpc-port", str(self.grpc_port)]
        self.proc = subprocess.Popen([sys.executable, "-m", "retarget", *argv, "--web", *ports], cwd=cwd, env=ENV,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)  # fmt: skip
        self.err = ""
        deadline = time.monotonic() + 60
        while "Ctrl-C to stop" not in self.err:
            assert self.proc.poll() is None and time.monotonic() < deadline, self.err
            self.err += self.proc.stderr.readline()  # type: ignore[union-attr]

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.web_port}/?url=rerun%2Bhttp://127.0.0.1:{self.grpc_port}/proxy"

    def interrupt(self) -> tuple[int, str]:
        self.proc.send_signal(signal.SIGINT)
        _, rest = self.proc.communicate(timeout=30)
        return self.proc.returncode, self.err + rest

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            self.proc.communicate(timeout=30)


def test_live_web_listens_on_loopback_only_and_ctrl_c_ends_it(tmp_path):
    served = Served("replay", "--dry-run", "--fast", "--max-ticks", "30", cwd=tmp_path)
    try:
        assert served.url in served.err
        for port in (served.web_port, served.grpc_port):
            assert listening(port) == ["0100007F"], port  # 127.0.0.1, and nothing on IPv6 or 0.0.0.0
    finally:
        code, err = served.interrupt()
    assert code == 130 and "Traceback" not in err and err.rstrip().endswith("retarget: interrupted"), err
    assert listening(served.web_port) == [] and listening(served.grpc_port) == []  # the server went with it


def test_web_on_a_busy_port_is_one_line_and_exit_2(capsys):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["view", "--end", "0.2", "--web", "--web-port", str(port)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--web-port" in err and str(port) in err and "free TCP port" in err, err


def test_a_recording_without_web_says_how_to_open_it(capsys, tmp_path):
    assert main(["view", str(tmp_path / "run.rrd")]) == 2
    assert "Expected --web" in capsys.readouterr().err


class Chromium:
    """Headless Chromium driven over the DevTools protocol on a pipe (``--remote-debugging-pipe``: fd 3 in,
    fd 4 out, NUL-separated JSON), so the test needs nothing beyond the standard library."""

    def __init__(self, url: str, profile) -> None:
        to_chrome, self._out = os.pipe()
        self._in, from_chrome = os.pipe()
        flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run", "--window-size=1280,800",
                 f"--user-data-dir={profile}", "--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE 127.0.0.1",
                 "--remote-debugging-pipe"]  # fmt: skip

        def fds() -> None:  # in the child: the pipe's ends on fd 3 and 4, inheritable (copies above 10 first)
            high = [fcntl.fcntl(fd, fcntl.F_DUPFD, 10) for fd in (to_chrome, from_chrome)]
            os.dup2(high[0], 3)
            os.dup2(high[1], 4)

        self.proc = subprocess.Popen([CHROMIUM, *flags, url], preexec_fn=fds, close_fds=False,  # noqa: PLW1509
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
        os.close(to_chrome)
        os.close(from_chrome)
        self._buf, self._id = b"", 0
        page = next(t for t in self.call("Target.getTargets")["targetInfos"] if t["type"] == "page")
        self.session = self.call("Target.attachToTarget", targetId=page["targetId"], flatten=True)["sessionId"]

    def call(self, method: str, session: str | None = None, **params: object) -> dict:
        self._id += 1
        message = {"id": self._id, "method": method, "params": params, **({"sessionId": session} if session else {})}
        os.write(self._out, json.dumps(message).encode() + b"\0")
        while True:
            while b"\0" not in self._buf:
                ready, _, _ = select.select([self._in], [], [], 30)
                chunk = os.read(self._in, 1 << 20) if ready else b""
                assert chunk, f"no answer from Chromium to {method}"
                self._buf += chunk
            raw, self._buf = self._buf.split(b"\0", 1)
            reply = json.loads(raw)
            if reply.get("id") == self._id:
                assert "error" not in reply, reply
                return dict(reply["result"])

    def screenshot(self) -> np.ndarray:
        """``(h, w, 3)`` uint8 RGB of the page."""
        png = base64.b64decode(self.call("Page.captureScreenshot", session=self.session, format="png")["data"])
        return (image.imread(io.BytesIO(png), format="png")[..., :3] * 255).round().astype(np.uint8)

    def close(self) -> None:
        try:
            self.call("Browser.close")
        finally:
            os.close(self._out)
            os.close(self._in)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def pixels_near(img: np.ndarray, colour: tuple[int, int, int], tol: int = 12) -> int:
    return int((np.abs(img.astype(int) - colour).max(axis=-1) <= tol).sum())


@pytest.mark.skipif(CHROMIUM is None, reason="no chromium on PATH (Debian: apt-get install chromium)")
def test_the_browser_viewer_shows_a_served_recording(tmp_path):
    rrd = tmp_path / "demo.rrd"
    assert main(["view", "--end", "1", "--record", str(rrd)]) == 0
    served = Served("view", str(rrd), cwd=tmp_path)
    browser = None
    try:
        browser = Chromium(served.url, tmp_path / "profile")
        deadline, shot = time.monotonic() + 60, None
        while time.monotonic() < deadline:  # the Wasm viewer loads, connects, fetches, draws (software GL)
            shot = browser.screenshot()
            if pixels_near(shot, ROBOT) > 600 and pixels_near(shot, CHAIN) > 200:
                break
            time.sleep(0.5)
        assert (
            shot is not None
        )  # a viewer without this recording: <= 151 such blue pixels (its selection) and no orange
        robot, chain = pixels_near(shot, ROBOT), pixels_near(shot, CHAIN)
        if not (robot > 600 and chain > 200):
            image.imsave(tmp_path / "seen.png", shot)
        assert robot > 600 and chain > 200, f"robot {robot}, arm chain {chain} pixels; see {tmp_path / 'seen.png'}"
    finally:
        if browser is not None:
            browser.close()
        code, err = served.interrupt()
    assert code == 130 and "Traceback" not in err, err


def test_a_server_that_does_not_start_is_one_line_and_exit_2(capsys, monkeypatch, tmp_path):
    fake = tmp_path / "rerun"
    fake.write_text("#!/bin/sh\necho 'Error: \\033[31mno web viewer in this build\\033[0m' >&2\nexit 3\n")
    fake.chmod(0o755)
    monkeypatch.setenv("RERUN_CLI_PATH", str(fake))
    web, grpc = free_ports(2)
    assert main(["view", "--end", "0.2", "--web", "--web-port", str(web), "--grpc-port", str(grpc)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "exited with 3: Error: no web viewer in this build" in err, err
