# SPDX-License-Identifier: Apache-2.0
"""erg.Client: ergd's JobService (proto/erg/v1/service.proto) as Python
calls, with the CLI's connection settings (erg/config.py), its retries of a
lost connection and its checked, resumable snapshot downloads."""
import hashlib
import json
import os
import secrets
import time
import warnings

import grpc
from google.protobuf import json_format
from google.protobuf.message import Message

from erg._proto import job_pb2, service_pb2, service_pb2_grpc
from erg import config

TERMINAL = (service_pb2.SUCCEEDED, service_pb2.FAILED, service_pb2.CANCELLED)
UNARY_TIMEOUT_S = 30
# A lost connection is retried as by `erg watch` and `erg fetch`: a backoff
# doubling up to 4 s, for up to 30 s without an answer.
RETRY_FOR_S = 30.0
RETRY_MAX_DELAY_S = 4.0


class Error(Exception):
    """A refused call: `code` is the grpc.StatusCode, `details` ergd's message."""

    def __init__(self, call, code, details):
        super().__init__("%s: %s: %s" % (call, code.name, details))
        self.call, self.code, self.details = call, code, details


def state_of(state):
    """A JobState from its number or name ("running", "SUCCEEDED")."""
    if isinstance(state, str):
        try:
            return service_pb2.JobState.Value(state.upper())
        except ValueError:
            raise ValueError("state: '%s' is not one of %s" % (state, ", ".join(
                n.lower() for n in service_pb2.JobState.keys()[1:]))) from None
    return int(state)


def spec_of(spec):
    """A JobSpec from a JobSpec, a dict, JSON text or the path of a JSON file."""
    if isinstance(spec, job_pb2.JobSpec):
        return spec
    if isinstance(spec, (str, os.PathLike)) and not str(spec).lstrip().startswith("{"):
        with open(spec, encoding="utf-8") as f:
            spec = f.read()
    if isinstance(spec, dict):
        spec = json.dumps(spec)
    return json_format.Parse(spec, job_pb2.JobSpec())


def events_of(events):
    """A list of Events from one Event or dict, a list of them, JSON text or
    the path of a JSON file (what `erg steer ID EVENTS.json` reads)."""
    if isinstance(events, os.PathLike) or (isinstance(events, str)
                                           and events.lstrip()[:1] not in ("[", "{")):
        with open(events, encoding="utf-8") as f:
            events = f.read()
    if isinstance(events, str):
        events = json.loads(events)
    if isinstance(events, (dict, Message)):
        events = [events]
    return [e if isinstance(e, job_pb2.Event) else json_format.ParseDict(e, job_pb2.Event())
            for e in events]


class _Retry:
    """Backoff for a lost connection; reset whenever ergd answers."""

    def __init__(self):
        self.reset()

    def reset(self):
        self.since, self.delay = None, 0.25

    def wait(self):
        """Sleeps before the next attempt; False once the budget is spent."""
        now = time.monotonic()
        if self.since is None:
            self.since = now
        if now - self.since >= RETRY_FOR_S:
            return False
        time.sleep(self.delay)
        self.delay = min(2 * self.delay, RETRY_MAX_DELAY_S)
        return True


def _lost(e):
    return isinstance(e, grpc.RpcError) and e.code() == grpc.StatusCode.UNAVAILABLE


class Client:
    """A connection to ergd as one tenant.

    server, token, ca: as `erg --server --token --ca`; None takes them from
    ERG_SERVER, ERG_TOKEN, ERG_CA, then the config file, as the CLI does.
    With a CA certificate (PEM file) the channel is TLS, else plaintext."""

    def __init__(self, server=None, token=None, ca=None):
        self.settings = config.resolve(server, token, ca)
        for w in self.settings.warnings:
            warnings.warn(w, stacklevel=2)
        self.server = self.settings.server
        self._metadata = ([("authorization", "Bearer " + self.settings.token)]
                          if self.settings.token else [])
        options = [("grpc.max_receive_message_length", 1 << 30)]
        if self.settings.ca:
            with open(self.settings.ca, "rb") as f:
                creds = grpc.ssl_channel_credentials(root_certificates=f.read())
            self._channel = grpc.secure_channel(self.server, creds, options)
        else:
            self._channel = grpc.insecure_channel(self.server, options)
        self._stub = service_pb2_grpc.JobServiceStub(self._channel)

    def close(self):
        self._channel.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _call(self, name, request, timeout=UNARY_TIMEOUT_S):
        try:
            return getattr(self._stub, name)(request, metadata=self._metadata, timeout=timeout)
        except grpc.RpcError as e:
            raise Error(name, e.code(), e.details()) from None

    def submit(self, spec, key=None, steps=None, snapshot_every=None, checkpoint_every=None,
               ranks=0, threads=0):
        """Queues a job; returns its erg.v1.Job (state QUEUED). `spec`: a
        JobSpec, a dict, JSON text or a JSON file's path; steps,
        snapshot_every, checkpoint_every override its `run` like `erg submit
        --steps ...`. `key` is an idempotency key (default: one per call, so
        that a retry after a lost reply cannot queue the job twice)."""
        spec = spec_of(spec)
        for name, value in (("steps", steps), ("snapshot_every", snapshot_every),
                            ("checkpoint_every", checkpoint_every)):
            if value is not None:
                setattr(spec.run, name, int(value))
        req = service_pb2.SubmitJobRequest(
            spec=spec, idempotency_key=key or "py-" + secrets.token_hex(8),
            resources=service_pb2.Resources(ranks=int(ranks), threads_per_rank=int(threads)))
        retry = _Retry()
        while True:
            try:
                return self._stub.SubmitJob(req, metadata=self._metadata,
                                            timeout=UNARY_TIMEOUT_S)
            except grpc.RpcError as e:
                # A server never reached is reported at once; a call lost on
                # the way is retried (the key makes it one job).
                if not _lost(e) or "failed to connect" in (e.details() or "") or not retry.wait():
                    raise Error("SubmitJob", e.code(), e.details()) from None

    def status(self, job_id):
        """The erg.v1.Job: state, progress, snapshot steps, ..."""
        return self._call("GetJob", service_pb2.GetJobRequest(id=job_id))

    def jobs(self, state=None, page_size=0):
        """Every job of the tenant (newest first), optionally of one state
        (a JobState or its name); pages are followed."""
        req = service_pb2.ListJobsRequest(page_size=page_size,
                                          state=0 if state is None else state_of(state))
        out = []
        while True:
            page = self._call("ListJobs", req)
            out.extend(page.jobs)
            if not page.next_page_token:
                return out
            req.page_token = page.next_page_token

    def watch(self, job_id, after_event_id=0):
        """The job's events (erg.v1.JobEvent: progress, state changes,
        snapshots, steering, notes) as they happen, until the job ends. A
        lost connection is retried and the stream resumes after the last
        event seen, so none is missed or repeated."""
        last = after_event_id
        retry = _Retry()
        while True:
            req = service_pb2.WatchJobRequest(id=job_id, after_event_id=last)
            try:
                for ev in self._stub.WatchJob(req, metadata=self._metadata):
                    retry.reset()
                    last = ev.id
                    yield ev
                return
            except grpc.RpcError as e:
                if not _lost(e) or not retry.wait():
                    raise Error("WatchJob", e.code(), e.details()) from None

    def wait(self, job_id):
        """Watches the job to its end; returns the final erg.v1.Job."""
        for _ in self.watch(job_id):
            pass
        return self.status(job_id)

    def cancel(self, job_id):
        """Cancels a queued or running job; returns the erg.v1.Job."""
        return self._call("CancelJob", service_pb2.CancelJobRequest(id=job_id))

    def resume(self, job_id):
        """Resumes a cancelled or failed job from its last checkpoint."""
        return self._call("ResumeJob", service_pb2.ResumeJobRequest(id=job_id))

    def steer(self, job_id, events):
        """Sends steering events (one erg.v1.Event or dict, a list, JSON
        text or a JSON file, as `erg steer`) to a RUNNING job; their `step`
        is ignored.
        Returns the events as applied, each with its step."""
        req = service_pb2.SteerJobRequest(id=job_id, events=events_of(events))
        return list(self._call("SteerJob", req).applied)

    def preview(self, job_id, step=None):
        """The PNG preview (bytes) of a snapshot step, default the latest."""
        req = service_pb2.GetPreviewRequest(id=job_id, step=step or 0, latest=step is None)
        return self._call("GetPreview", req).png

    def fetch(self, job_id, out, step=None, all=False):
        """Downloads the latest snapshot (or `step`, or `all` of them) into
        the folder `out`, as `erg fetch`: into NAME.part, resumed from its
        size after an interruption, checked against ergd's sha256, renamed
        to NAME when whole. A file already there with the right sha256 is
        kept. Returns the paths, in step order."""
        os.makedirs(out, exist_ok=True)
        if all:
            steps = list(self.status(job_id).snapshot_steps)
        elif step is None:
            job = self.status(job_id)
            if not job.snapshot_steps:
                raise Error("StreamSnapshot", grpc.StatusCode.FAILED_PRECONDITION,
                            "job %s has no snapshot yet (%s)"
                            % (job_id, service_pb2.JobState.Name(job.state)))
            steps = [job.snapshot_steps[-1]]
        else:
            steps = [int(step)]
        return [self._fetch_step(job_id, s, out) for s in steps]

    def _fetch_step(self, job_id, step, out):
        retry = _Retry()
        name = "step_%08d.h5" % step
        checked_existing = False
        renamed = 0
        while True:
            final = os.path.join(out, name)
            part = final + ".part"
            check = not checked_existing and os.path.exists(final)
            offset = 0 if check or not os.path.exists(part) else os.path.getsize(part)
            req = service_pb2.StreamSnapshotRequest(id=job_id, step=step, offset=offset)
            try:
                stream = self._stub.StreamSnapshot(req, metadata=self._metadata)
                first = next(stream, None)
                if first is None:
                    raise Error("StreamSnapshot", grpc.StatusCode.DATA_LOSS, "empty stream")
                retry.reset()
                if first.step != step:
                    stream.cancel()
                    raise Error("StreamSnapshot", grpc.StatusCode.DATA_LOSS,
                                "ergd sent step %d for step %d" % (first.step, step))
                if os.path.basename(first.name) != first.name or first.name in ("", ".", ".."):
                    stream.cancel()
                    raise Error("StreamSnapshot", grpc.StatusCode.DATA_LOSS,
                                "refusing ergd's file name '%s'" % first.name)
                if first.name != name:  # ergd names it otherwise: look for that .part
                    stream.cancel()
                    renamed += 1
                    if renamed > 2:
                        raise Error("StreamSnapshot", grpc.StatusCode.DATA_LOSS,
                                    "ergd keeps renaming step %d" % step)
                    name = first.name
                    continue
                if check:
                    stream.cancel()
                    checked_existing = True
                    if _sha256_of(final) == first.sha256:
                        return final
                    continue
                with open(part, "r+b" if offset else "wb") as f:
                    f.seek(offset)
                    f.truncate()
                    for chunk in _chain(first, stream):
                        if chunk.offset != f.tell():
                            raise Error("StreamSnapshot", grpc.StatusCode.DATA_LOSS,
                                        "chunk at byte %d, expected %d" % (chunk.offset, f.tell()))
                        f.write(chunk.data)
                    f.flush()
                    os.fsync(f.fileno())
            except grpc.RpcError as e:
                if _lost(e) and retry.wait():
                    continue
                if e.code() == grpc.StatusCode.OUT_OF_RANGE and offset > 0:
                    os.remove(part)  # a .part longer than ergd's file is not its start
                    continue
                raise Error("StreamSnapshot", e.code(), e.details()) from None
            if os.path.getsize(part) != first.size or _sha256_of(part) != first.sha256:
                os.remove(part)
                raise Error("StreamSnapshot", grpc.StatusCode.DATA_LOSS,
                            "%s: sha256 differs from ergd's; the .part was deleted" % final)
            os.replace(part, final)
            return final


def _chain(first, rest):
    yield first
    yield from rest


def _sha256_of(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
