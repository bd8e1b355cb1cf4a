"""Issue 13, item 5: signals during --view leave no meshcat server behind (process table)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

pytest.importorskip("meshcat")

CHILD = textwrap.dedent("""
    import sys
    sys.stdin.isatty = lambda: True  # make the CLI wait in input() as in a terminal
    from geoddp.cli import main
    sys.exit(main(["run", "satellite_paper", "--quiet", "--view"]))
""")


def _children(pid: int) -> list[int]:
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.append(int(d))
    return out


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start_viewing():
    # SIGINT at its default in the child: a shell starts background jobs (`cmd &`) with SIGINT ignored,
    # and a child inherits that, so a suite run in the background would test nothing here.
    proc = subprocess.Popen([sys.executable, "-c", CHILD], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=os.environ.copy(), preexec_fn=_default_sigint)
    deadline = time.time() + 120
    buf = b""
    while b"Replaying" not in buf and time.time() < deadline:
        chunk = os.read(proc.stdout.fileno(), 4096)
        if not chunk:
            break
        buf += chunk
    if b"Replaying" not in buf:
        proc.kill()
        pytest.fail(f"the viewer did not start: {buf!r} {proc.stderr.read()!r}")
    servers = _children(proc.pid)
    assert servers and all(_alive(p) for p in servers)
    return proc, servers


@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGHUP, 129), (signal.SIGINT, 130)])
def test_signal_during_view_stops_the_server(sig, code):
    proc, servers = _start_viewing()
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == code
    assert err.decode().strip().splitlines() == [f"geoddp: interrupted by {signal.Signals(sig).name}; no output written"]
    assert not any(_alive(p) for p in servers), "a meshcat server outlived geoddp"


def test_sigkill_of_geoddp_stops_the_server_within_seconds():
    proc, servers = _start_viewing()
    proc.kill()
    proc.wait(10)
    deadline = time.time() + 5
    while any(_alive(p) for p in servers) and time.time() < deadline:
        time.sleep(0.1)
    assert not any(_alive(p) for p in servers)
