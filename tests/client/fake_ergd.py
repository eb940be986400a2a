"""A scripted stand-in for ergd, to test the erg client's remote commands.

It speaks erg.v1.JobService (modules generated from proto/ at build time,
ERG_PYTHON_PROTO_DIR) on loopback, in this process, and can misbehave on
cue: break a WatchJob stream after some events, cut a snapshot download
half-way, announce a wrong sha256. It records every request so tests can
check what the client asked for (resume offsets, event ids).
"""
import hashlib
import os
import sys
import threading
import time
from concurrent import futures

sys.path.insert(0, os.environ["ERG_PYTHON_PROTO_DIR"])

import grpc  # noqa: E402

from erg.v1 import job_pb2 as J  # noqa: E402
from erg.v1 import service_pb2 as S  # noqa: E402
from erg.v1 import service_pb2_grpc as G  # noqa: E402

TOKEN = "tok-test-0123456789"
CHUNK = 64 * 1024


def snapshot_bytes(job_id, step, size=300 * 1024 + 17):
    """Deterministic content of a job's snapshot of `step`."""
    seed = hashlib.sha256(f"{job_id}/{step}".encode()).digest()
    out = bytearray()
    while len(out) < size:
        seed = hashlib.sha256(seed).digest()
        out += seed
    return bytes(out[:size])


class Behaviour:
    """What the fake does wrong, set by the tests between commands."""

    def __init__(self):
        self.watch_break_after = []  # per WatchJob call, in order: break after N events
        self.snapshot_break_at = []  # per StreamSnapshot call: stop after N bytes (UNAVAILABLE)
        self.wrong_sha = False
        self.watch_final = S.SUCCEEDED
        self.watch_delay_s = 0.0


class FakeErgd(G.JobServiceServicer):
    def __init__(self):
        self.lock = threading.Lock()
        self.jobs = {}  # id -> S.Job
        self.keys = {}
        self.requests = []  # (method, request message)
        self.behaviour = Behaviour()
        self.next = 1

    # -- helpers ---------------------------------------------------------------
    def _auth(self, context):
        md = dict(context.invocation_metadata())
        if md.get("authorization") != "Bearer " + TOKEN:
            context.abort(grpc.StatusCode.UNAUTHENTICATED, "no or unknown bearer token")

    def _record(self, method, request):
        with self.lock:
            self.requests.append((method, request))

    def _job(self, job_id, context):
        job = self.jobs.get(job_id)
        if job is None:
            context.abort(grpc.StatusCode.NOT_FOUND, f"no job {job_id}")
        return job

    def add_job(self, state=S.SUCCEEDED, steps=40, snapshot_every=10, name="fake", **fields):
        with self.lock:
            job_id = "j-%016x" % (0xABC000 + self.next)
            self.next += 1
            job = S.Job(id=job_id, tenant="t", state=state, **fields)
            job.spec.name = name
            job.spec.domain.nx = 64
            job.spec.domain.ny = 32
            job.spec.run.steps = steps
            job.spec.run.snapshot_every = snapshot_every
            job.progress.total_steps = steps
            job.created_unix_ms = int(time.time() * 1000) - self.next * 1000
            if state in (S.SUCCEEDED,):
                job.progress.step = steps
                job.snapshot_steps.extend(range(0, steps + 1, snapshot_every))
                job.progress.sand_units_total = "123456789012345678901"
                job.progress.airborne_units_total = "0"
            self.jobs[job_id] = job
            return job

    # -- the service -----------------------------------------------------------
    def SubmitJob(self, request, context):
        self._auth(context)
        self._record("SubmitJob", request)
        if request.idempotency_key in self.keys:
            return self.jobs[self.keys[request.idempotency_key]]
        job = self.add_job(state=S.QUEUED, steps=request.spec.run.steps,
                           snapshot_every=request.spec.run.snapshot_every,
                           name=request.spec.name)
        job.spec.CopyFrom(request.spec)
        job.resources.CopyFrom(request.resources)
        job.idempotency_key = request.idempotency_key
        self.keys[request.idempotency_key] = job.id
        return job

    def GetJob(self, request, context):
        self._auth(context)
        self._record("GetJob", request)
        return self._job(request.id, context)

    def ListJobs(self, request, context):
        self._auth(context)
        self._record("ListJobs", request)
        jobs = sorted(self.jobs.values(), key=lambda j: -j.created_unix_ms)
        if request.state:
            jobs = [j for j in jobs if j.state == request.state]
        size = request.page_size or 50
        start = int(request.page_token or 0)
        page = jobs[start:start + size]
        nxt = str(start + size) if start + size < len(jobs) else ""
        return S.ListJobsResponse(jobs=page, next_page_token=nxt)

    def CancelJob(self, request, context):
        self._auth(context)
        self._record("CancelJob", request)
        job = self._job(request.id, context)
        if job.state == S.QUEUED:
            job.state = S.CANCELLED
        return job

    def _events(self, job):
        """The job's whole event history: a run to its final state."""
        steps = job.spec.run.steps or 40
        every = job.spec.run.snapshot_every or 10
        evs = [S.JobEvent(state=S.RUNNING, state_changed=S.RUNNING)]
        evs.append(S.JobEvent(state=S.RUNNING, message="worker started on 1 rank(s)"))
        for step in range(0, steps + 1, every):
            p = S.Progress(step=step, total_steps=steps, steps_per_s=12.5,
                           eta_s=(steps - step) / 12.5, sand_units_total="42")
            evs.append(S.JobEvent(state=S.RUNNING, progress=p))
            evs.append(S.JobEvent(state=S.RUNNING, snapshot_step=step))
            if step == every:
                ev = J.Event(step=step)
                ev.sand.x_m, ev.sand.y_m, ev.sand.radius_m, ev.sand.height = 10, 20, 5, 2
                evs.append(S.JobEvent(state=S.RUNNING, steered=ev))
        final = self.behaviour.watch_final
        evs.append(S.JobEvent(state=final, state_changed=final))
        for i, e in enumerate(evs):
            e.id = i + 1
            e.unix_ms = 1700000000000 + i
        return evs

    def WatchJob(self, request, context):
        self._auth(context)
        self._record("WatchJob", request)
        job = self._job(request.id, context)
        with self.lock:
            brk = self.behaviour.watch_break_after.pop(0) if self.behaviour.watch_break_after \
                else None
        sent = 0
        for ev in self._events(job):
            if ev.id <= request.after_event_id:
                continue
            if brk is not None and sent >= brk:
                context.abort(grpc.StatusCode.UNAVAILABLE, "fake ergd: connection lost")
            if self.behaviour.watch_delay_s:
                time.sleep(self.behaviour.watch_delay_s)
            yield ev
            sent += 1
        final = self.behaviour.watch_final
        job.state = final
        if final == S.FAILED:
            job.failure_reason = "erg-worker exited with status 1"
            job.log_tail = "erg: step 20: out of memory\nerg: giving up"

    def StreamSnapshot(self, request, context):
        self._auth(context)
        self._record("StreamSnapshot", request)
        job = self._job(request.id, context)
        step = max(job.snapshot_steps) if request.latest else request.step
        if step not in job.snapshot_steps:
            context.abort(grpc.StatusCode.NOT_FOUND, f"no snapshot at step {step}")
        data = snapshot_bytes(job.id, step)
        if request.offset > len(data):
            context.abort(grpc.StatusCode.OUT_OF_RANGE, "offset past the end")
        sha = hashlib.sha256(data).hexdigest()
        if self.behaviour.wrong_sha:
            sha = hashlib.sha256(b"something else").hexdigest()
        with self.lock:
            brk = self.behaviour.snapshot_break_at.pop(0) if self.behaviour.snapshot_break_at \
                else None
        off = request.offset
        first = True
        while first or off < len(data):
            end = min(off + CHUNK, len(data))
            if brk is not None and end > brk:
                context.abort(grpc.StatusCode.UNAVAILABLE, "fake ergd: connection lost")
            msg = S.SnapshotChunk(offset=off, data=data[off:end])
            if first:
                msg.size, msg.step, msg.sha256 = len(data), step, sha
                msg.name = "step_%08d.h5" % step
            yield msg
            first = False
            off = end

    def GetPreview(self, request, context):
        self._auth(context)
        self._record("GetPreview", request)
        job = self._job(request.id, context)
        step = max(job.snapshot_steps) if request.latest else request.step
        if step not in job.snapshot_steps:
            context.abort(grpc.StatusCode.NOT_FOUND, f"no preview at step {step}")
        return S.Preview(step=step, png=b"\x89PNG\r\n\x1a\n" + bytes(100))

    def SteerJob(self, request, context):
        self._auth(context)
        self._record("SteerJob", request)
        job = self._job(request.id, context)
        if job.state != S.RUNNING:
            context.abort(grpc.StatusCode.FAILED_PRECONDITION,
                          f"job {job.id} is {S.JobState.Name(job.state)}, not RUNNING")
        applied = []
        for e in request.events:
            a = J.Event()
            a.CopyFrom(e)
            a.step = job.progress.step + 1
            applied.append(a)
        job.spec.events.extend(applied)
        return S.SteerJobResponse(applied=applied, job=job)


class Server:
    """The fake on a free loopback port."""

    def __init__(self, port=0):
        self.fake = FakeErgd()
        self.server = grpc.server(futures.ThreadPoolExecutor(max_workers=8))
        G.add_JobServiceServicer_to_server(self.fake, self.server)
        self.port = self.server.add_insecure_port(f"127.0.0.1:{port}")
        self.server.start()

    @property
    def address(self):
        return f"127.0.0.1:{self.port}"

    def stop(self):
        self.server.stop(grace=None).wait()
