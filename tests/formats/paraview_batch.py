# SPDX-License-Identifier: Apache-2.0
"""ParaView's pvbatch on an XDMF file, under an X server of its own.

Debian's ParaView renders through X, so pvbatch needs a display. `xvfb-run -a`
picks its display by looking for a free lock file and then starts Xvfb: two
tests doing so at once (ctest -j) can pick the same display, and the loser's
pvbatch then meets the winner's server with the wrong cookie and aborts
("bad X server connection"). Here Xvfb chooses the display itself
(-displayfd): it takes the first display whose lock it can create, which is
atomic, and writes the number back once it accepts connections. It runs
with -noreset: by default an X server resets when its last client
disconnects, and a client that connects, disconnects and connects again
(VTK probing the display before opening its window) can meet the server in
that reset and abort the same way; seen once under ctest -j2 with a
display of this module's own."""
import contextlib
import json
import os
import subprocess
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
PV_INSPECT = os.path.join(HERE, "pv_inspect.py")


@contextlib.contextmanager
def virtual_display():
    """An Xvfb of this process's own, on local sockets only; yields DISPLAY,
    the server's process and a function that returns what it wrote to
    stderr."""
    # The server's stderr goes to a file, not a pipe nobody reads while it
    # runs: a full pipe would stall the server (its keymap compiler's
    # warnings come at every start).
    log = tempfile.TemporaryFile(mode="w+")
    r, w = os.pipe()
    try:
        xvfb = subprocess.Popen(["Xvfb", "-displayfd", str(w), "-screen", "0", "1280x1024x24",
                                 "-nolisten", "tcp", "-noreset"], pass_fds=(w,), stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=log)
    finally:
        os.close(w)
    with os.fdopen(r) as f:
        number = f.readline().strip()  # "" (EOF) if Xvfb exited instead

    def said():
        log.seek(0)
        return log.read()[-4000:]

    try:
        if not number.isdigit():
            xvfb.kill()
            xvfb.wait()
            raise AssertionError(f"Xvfb did not start: {said()}")
        yield f":{number}", xvfb, said
    finally:
        if xvfb.poll() is None:
            xvfb.terminate()
            try:
                xvfb.wait(timeout=30)
            except subprocess.TimeoutExpired:
                xvfb.kill()
                xvfb.wait()
        log.close()


def inspect(xdmf, screenshot=None):
    """What ParaView sees in `xdmf` (pv_inspect.py's JSON); with `screenshot`,
    also a warped, coloured rendering written there."""
    cmd = ["pvbatch", PV_INSPECT, xdmf] + ([screenshot] if screenshot else [])
    with virtual_display() as (display, xvfb, said):
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=300,
                           env=dict(os.environ, DISPLAY=display))
        lines = [ln for ln in p.stdout.splitlines() if ln.startswith("ERG_PV ")]
        if p.returncode != 0 or not lines:
            # Whether the X server was still there, and what it said.
            server = "running" if xvfb.poll() is None else f"exited {xvfb.returncode}"
            raise AssertionError(f"pvbatch exited {p.returncode} on {display} (Xvfb {server}):\n"
                                 f"{p.stdout}\n{p.stderr}\nXvfb's stderr:\n{said()}")
    return json.loads(lines[-1][len("ERG_PV "):])
