# SPDX-License-Identifier: Apache-2.0
"""Starts a real ergd on loopback for the service tests.

Everything is real: the ergd binary, its SQLite store, the erg-worker
processes it launches, the gRPC channel (python3-grpcio with modules
generated from proto/erg/v1 at build time). Paths come from the environment
ctest sets (tests/server/CMakeLists.txt): ERG_BIN_DIR, ERG_PYTHON_PROTO_DIR.
"""
import hashlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import unittest
import urllib.request

sys.path.insert(0, os.environ["ERG_PYTHON_PROTO_DIR"])

import grpc  # noqa: E402
import h5py  # noqa: E402
import numpy as np  # noqa: E402
from google.protobuf import json_format  # noqa: E402

from erg.v1 import job_pb2 as J  # noqa: E402
from erg.v1 import service_pb2 as S  # noqa: E402
from erg.v1 import service_pb2_grpc as G  # noqa: E402

BIN = os.environ["ERG_BIN_DIR"]
ERGD = os.path.join(BIN, "ergd")
ERG = os.path.join(BIN, "erg")

ALICE = "tok-alice-0123456789abcdef"
BOB = "tok-bob-0123456789abcdef00"
CAROL = "tok-carol-0123456789abcdef"
OPERATOR = "tok-operator-0123456789abc"  # role operator: every tenant's /metrics


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def self_signed_cert(tmp):
    """(cert.pem, key.pem) in tmp: a certificate for localhost and 127.0.0.1
    made by the openssl CLI."""
    cert, key = os.path.join(tmp, "cert.pem"), os.path.join(tmp, "key.pem")
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2",
                    "-subj", "/CN=localhost", "-addext",
                    "subjectAltName=DNS:localhost,IP:127.0.0.1",
                    "-keyout", key, "-out", cert], check=True, capture_output=True)
    return cert, key


def spec_json(nx=64, ny=64, steps=40, snapshot_every=10, checkpoint_every=20, name="test",
              **extra):
    d = {
        "name": name,
        "domain": {"nx": nx, "ny": ny, "cell_size_m": 1},
        "layers": {"sand": {"fbm": {"amplitude": 1.0, "offset": 1.5, "wavelength_m": 32}}},
        "wind": {"constant": {"speed_mps": 6, "direction_deg": 20}},
        "transport": "STOCHASTIC",
        "model": {"slab_m": 0.05, "reptation_k": 0.2, "avalanche_iterations": 12},
        "run": {"steps": steps, "snapshot_every": snapshot_every,
                "checkpoint_every": checkpoint_every},
    }
    d.update(extra)
    return d


def spec_of(d):
    return json_format.Parse(json.dumps(d), J.JobSpec())


def md(token):
    return [("authorization", "Bearer " + token)]


class NoRedirect(urllib.request.HTTPRedirectHandler):
    """For urllib openers that must see a redirect (e.g. /login's 303 and its
    Set-Cookie) instead of following it."""

    def redirect_request(self, *args, **kwargs):
        return None


def terminal(state):
    return state in (S.SUCCEEDED, S.FAILED, S.CANCELLED)


class Ergd:
    """One ergd process with its own data directory and ports."""

    def __init__(self, tmp, extra_args=(), data=None, port=None, http_port=None, ca=None):
        """ca: the PEM certificate of a TLS ergd (extra_args name its
        --tls-cert/--tls-key); the fixture's channel then verifies it."""
        self.tmp = tmp
        self.ca = ca
        self.data = data or os.path.join(tmp, "data")
        self.port = port or free_port()
        self.http_port = http_port or free_port()
        self.tokens = os.path.join(tmp, "tokens")
        if not os.path.exists(self.tokens):
            with open(self.tokens, "w") as f:
                f.write("# test tokens\n%s alice\n%s bob\n%s carol\n%s ops operator\n"
                        % (ALICE, BOB, CAROL, OPERATOR))
        self.extra = list(extra_args)
        self.log = os.path.join(tmp, "ergd.log")
        self.proc = None
        self.start()

    @property
    def addr(self):
        return "127.0.0.1:%d" % self.port

    @property
    def http(self):
        return "http://127.0.0.1:%d" % self.http_port

    def raw_get(self, path, token):
        """GET path as sent, byte for byte (no client-side normalisation of
        the path), and the whole answer once ergd closes the connection."""
        with socket.create_connection(("127.0.0.1", self.http_port), timeout=10) as s:
            s.sendall(("GET %s HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer %s\r\n"
                       "Connection: close\r\n\r\n" % (path, token)).encode())
            answer = b""
            while True:
                chunk = s.recv(65536)
                if not chunk:
                    return answer
                answer += chunk

    def start(self):
        with open(self.log, "a") as logf:
            self.proc = subprocess.Popen(
                [ERGD, "--listen", self.addr, "--http", "127.0.0.1:%d" % self.http_port,
                 "--data", self.data, "--tokens", self.tokens, "--cancel-grace", "10"]
                + self.extra, stdout=logf, stderr=subprocess.STDOUT)
        if self.ca:
            with open(self.ca, "rb") as f:
                creds = grpc.ssl_channel_credentials(root_certificates=f.read())
            self.channel = grpc.secure_channel(self.addr, creds)
        else:
            self.channel = grpc.insecure_channel(self.addr)
        self.stub = G.JobServiceStub(self.channel)
        grpc.channel_ready_future(self.channel).result(timeout=30)

    def kill(self):
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait()
        self.channel.close()

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.channel.close()

    def submit(self, d, token=ALICE, key="", ranks=0, threads=1):
        return self.stub.SubmitJob(
            S.SubmitJobRequest(spec=spec_of(d), idempotency_key=key,
                               resources=S.Resources(ranks=ranks, threads_per_rank=threads)),
            metadata=md(token), timeout=30)

    def get(self, job_id, token=ALICE):
        return self.stub.GetJob(S.GetJobRequest(id=job_id), metadata=md(token), timeout=30)

    def wait(self, job_id, token=ALICE, timeout=120, until=terminal):
        t0 = time.time()
        while time.time() - t0 < timeout:
            j = self.get(job_id, token)
            if until(j.state) if until is terminal else until(j):
                return j
            time.sleep(0.1)
        raise AssertionError("job %s did not get there in %d s: %s" % (job_id, timeout, j))

    def kill_and_restart_under(self, client, job_id, until, token=ALICE, timeout=120):
        """SIGKILLs ergd once job_id gets `until` (see wait) while `client`
        (a Popen watching the job with stdout and stderr piped) runs,
        restarts it on the same data and ports, and returns the client's
        (stdout, stderr) once it ends. Fails when the client gave up at the kill."""
        try:
            self.wait(job_id, token, until=until)
            self.kill()  # SIGKILL: the stream breaks, the worker checkpoints and stops
            time.sleep(1.0)
            if client.poll() is not None:
                raise AssertionError("the client gave up at once: " + client.stderr.read())
            self.start()
            return client.communicate(timeout=timeout)
        finally:
            if client.poll() is None:
                client.kill()
                client.wait()

    def fetch_bytes(self, job_id, token=ALICE, step=None, offset=0):
        req = S.StreamSnapshotRequest(id=job_id, latest=step is None, step=step or 0,
                                      offset=offset)
        first, data = None, b""
        for c in self.stub.StreamSnapshot(req, metadata=md(token), timeout=60):
            if first is None:
                first = c
            assert len(c.data) <= 1 << 20
            assert c.offset == offset + len(data)
            data += c.data
        return first, data


def datasets(path):
    """Every dataset of an HDF5 file, and the file's attributes."""
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                out[name] = np.array(obj[()])
        f.visititems(visit)
        out["@attrs"] = {k: (v.tolist() if hasattr(v, "tolist") else v) for k, v in f.attrs.items()
                         if k not in ("created", "wall_seconds")}
    return out


def erg_run(d, out_dir, tmp):
    """The same spec run locally with `erg run` (the reference)."""
    path = os.path.join(tmp, "local-%d.json" % abs(hash(out_dir)))
    with open(path, "w") as f:
        json.dump(d, f)
    subprocess.run([ERG, "run", path, "--out", out_dir, "--threads", "2"], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return out_dir


class ErgdTest(unittest.TestCase):
    """Base: a fresh ergd per test class, stopped (and its jobs) at the end."""

    extra_args = ()

    @classmethod
    def setUpClass(cls):
        cls.tmpdir = tempfile.mkdtemp(prefix="ergd-test-", dir=os.environ.get("ERG_TEST_TMP"))
        cls.ergd = Ergd(cls.tmpdir, cls.extra_args)

    @classmethod
    def tearDownClass(cls):
        cls.ergd.stop()
        if os.environ.get("ERG_KEEP_TEST_DIRS") != "1":
            shutil.rmtree(cls.tmpdir, ignore_errors=True)

    def assertSameSnapshot(self, a, b):
        da, db = datasets(a), datasets(b)
        self.assertEqual(sorted(da), sorted(db))
        for k in da:
            if k == "@attrs":
                continue
            self.assertTrue(np.array_equal(da[k], db[k]), "dataset %s differs" % k)
        for k in ("sand_units_total", "airborne_units_total", "bedrock_units_total", "step"):
            if k in da["@attrs"]:
                self.assertEqual(da["@attrs"][k], db["@attrs"].get(k), k)


def sha256(data):
    return hashlib.sha256(data).hexdigest()
