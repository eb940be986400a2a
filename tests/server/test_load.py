# SPDX-License-Identifier: Apache-2.0
"""A bounded load on loopback: 20 queued jobs from two tenants, 50
concurrent watchers, repeated snapshot fetches and a GetJob poller, all at
once. Checks that nothing is lost or stuck (every job succeeds, every
watcher sees its job's final event, every fetch verifies) and prints
ergd's peak memory, GetJob latency percentiles and streaming throughput
(README, "Service load"). Set ERG_LOAD_REPORT=FILE to keep the numbers."""
import json
import os
import threading
import time
import unittest

import grpc

from ergd_fixture import ALICE, BOB, ErgdTest, S, md, sha256, spec_json, terminal

JOBS = 20
WATCHERS = 50
FETCHERS = 4


def vm_hwm_bytes(pid):
    with open("/proc/%d/status" % pid) as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    return 0


class Load(ErgdTest):
    extra_args = ("--max-running", "2")

    def test_watchers_queue_and_fetches_together(self):
        e = self.ergd
        # A big snapshot to stream (512^2: a few MB), finished before the load.
        big = e.submit(spec_json(name="big", nx=512, ny=512, steps=2, snapshot_every=0,
                                 checkpoint_every=0), threads=2)
        e.wait(big.id, timeout=300)
        jobs = []
        for i in range(JOBS):
            token = ALICE if i % 2 == 0 else BOB
            j = e.submit(spec_json(name="load-%d" % i, steps=150, snapshot_every=50,
                                   checkpoint_every=0), token=token)
            jobs.append((j.id, token))
        errors, finals = [], {}
        lock = threading.Lock()

        def watch(k):
            job_id, token = jobs[k % JOBS]
            last = 0
            for attempt in range(3):
                try:
                    for ev in e.stub.WatchJob(S.WatchJobRequest(id=job_id, after_event_id=last),
                                              metadata=md(token), timeout=600):
                        last = ev.id
                        if ev.HasField("state_changed") and terminal(ev.state_changed):
                            with lock:
                                finals[k] = ev.state_changed
                    return
                except grpc.RpcError as err:
                    with lock:
                        errors.append("watch %d: %s" % (k, err))

        latencies = []
        stop = threading.Event()

        def poll():
            i = 0
            while not stop.is_set():
                job_id, token = jobs[i % JOBS]
                t0 = time.perf_counter()
                e.stub.GetJob(S.GetJobRequest(id=job_id), metadata=md(token), timeout=30)
                latencies.append(time.perf_counter() - t0)
                i += 1
                time.sleep(0.005)

        streamed = [0]

        def fetch():
            while not stop.is_set():
                try:
                    first, data = e.fetch_bytes(big.id)
                    if first.sha256 != sha256(data) or first.size != len(data):
                        with lock:
                            errors.append("fetch: checksum or size mismatch")
                    with lock:
                        streamed[0] += len(data)
                except grpc.RpcError as err:
                    with lock:
                        errors.append("fetch: %s" % err)

        watchers = [threading.Thread(target=watch, args=(k,)) for k in range(WATCHERS)]
        pollers = [threading.Thread(target=poll)]
        fetchers = [threading.Thread(target=fetch) for _ in range(FETCHERS)]
        t0 = time.time()
        for t in watchers + pollers + fetchers:
            t.start()
        for t in watchers:
            t.join(timeout=600)
        elapsed = time.time() - t0
        stop.set()
        for t in pollers + fetchers:
            t.join(timeout=120)

        self.assertEqual(errors, [])
        self.assertEqual(len(finals), WATCHERS)
        self.assertTrue(all(s == S.SUCCEEDED for s in finals.values()), finals)
        for job_id, token in jobs:
            self.assertEqual(e.get(job_id, token).state, S.SUCCEEDED)
        latencies.sort()
        pct = lambda p: latencies[min(len(latencies) - 1, int(p * len(latencies)))]  # noqa: E731
        report = {
            "jobs": JOBS, "watchers": WATCHERS, "fetchers": FETCHERS,
            "wall_s": round(elapsed, 2),
            "ergd_peak_rss_mib": round(vm_hwm_bytes(e.proc.pid) / 2**20, 1),
            "getjob_calls": len(latencies),
            "getjob_p50_ms": round(pct(0.50) * 1e3, 2),
            "getjob_p99_ms": round(pct(0.99) * 1e3, 2),
            "streamed_mib": round(streamed[0] / 2**20, 1),
            "stream_mib_per_s": round(streamed[0] / 2**20 / elapsed, 1),
        }
        print("load:", json.dumps(report))
        if os.environ.get("ERG_LOAD_REPORT"):
            with open(os.environ["ERG_LOAD_REPORT"], "w") as f:
                json.dump(report, f, indent=1)
        self.assertGreater(len(latencies), 10)
        self.assertGreater(streamed[0], 0)
        # Loose bounds: they catch a stuck server, not a slow machine.
        self.assertLess(report["getjob_p99_ms"], 2000)
        self.assertLess(report["ergd_peak_rss_mib"], 2048)


if __name__ == "__main__":
    unittest.main()
