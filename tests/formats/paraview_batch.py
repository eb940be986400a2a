# SPDX-License-Identifier: Apache-2.0
"""ParaView's pvbatch on an XDMF file, under an X server of its own.

Debian's ParaView renders through X, so pvbatch needs a display. `xvfb-run -a`
picks its display by looking for a free lock file and then starts Xvfb: two
tests doing so at once (ctest -j) can pick the same display, and the loser's
pvbatch then meets the winner's server with the wrong cookie and aborts
("bad X server connection"). Here Xvfb chooses the display itself
(-displayfd): it takes the first display whose lock it can create, which is
atomic, and writes the number back once it accepts connections."""
import contextlib
import json
import os
import subprocess

HERE = os.path.dirname(os.path.abspath(__file__))
PV_INSPECT = os.path.join(HERE, "pv_inspect.py")


@contextlib.contextmanager
def virtual_display():
    """An Xvfb of this process's own, on local sockets only; yields DISPLAY."""
    r, w = os.pipe()
    try:
        xvfb = subprocess.Popen(["Xvfb", "-displayfd", str(w), "-screen", "0", "1280x1024x24",
                                 "-nolisten", "tcp"], pass_fds=(w,), stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    finally:
        os.close(w)
    with os.fdopen(r) as f:
        number = f.readline().strip()  # "" (EOF) if Xvfb exited instead
    try:
        if not number.isdigit():
            xvfb.kill()
            raise AssertionError(f"Xvfb did not start: {xvfb.communicate()[1]}")
        yield f":{number}"
    finally:
        if xvfb.poll() is None:
            xvfb.terminate()
            try:
                xvfb.wait(timeout=30)
            except subprocess.TimeoutExpired:
                xvfb.kill()
                xvfb.wait()


def inspect(xdmf, screenshot=None):
    """What ParaView sees in `xdmf` (pv_inspect.py's JSON); with `screenshot`,
    also a warped, coloured rendering written there."""
    cmd = ["pvbatch", PV_INSPECT, xdmf] + ([screenshot] if screenshot else [])
    with virtual_display() as display:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=300,
                           env=dict(os.environ, DISPLAY=display))
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("ERG_PV ")]
    if p.returncode != 0 or not lines:
        raise AssertionError(f"pvbatch exited {p.returncode}:\n{p.stdout}\n{p.stderr}")
    return json.loads(lines[-1][len("ERG_PV "):])
