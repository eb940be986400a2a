# SPDX-License-Identifier: Apache-2.0
"""The dashboard's sign-in and /metrics: /metrics shows a tenant only its
own series (an operator token sees all); sign-in is throttled per client
address and refuses cross-site requests; the session cookie is HttpOnly,
SameSite=Strict and holds no token (Secure under TLS: server.tls)."""
import time
import unittest

from ergd_fixture import ALICE, BOB, OPERATOR, ErgdTest, S, md, spec_json
from sec_util import bearer, form, request, session_of


class HttpAuth(ErgdTest):
    def test_metrics_are_per_tenant_unless_operator(self):
        port = self.ergd.http_port
        job = self.ergd.submit(spec_json(steps=1000000, snapshot_every=0, checkpoint_every=0,
                                         name="metered"))
        try:
            self.ergd.wait(job.id, until=lambda j: j.progress.steps_per_s > 0, timeout=60)
            deadline = time.monotonic() + 10
            while time.monotonic() < deadline:  # the rate gauge follows progress
                _, _, mine = request(port, "GET", "/metrics", bearer(ALICE))
                if job.id.encode() in mine:
                    break
                time.sleep(0.2)
            self.assertIn(('erg_job_steps_per_second{job="%s",tenant="alice"}' % job.id).encode(),
                          mine)
            self.assertNotIn(b"erg_rpc_latency_seconds", mine)  # server-wide: operators only
            self.assertNotIn(b"erg_jobs{", mine)
            _, _, bobs = request(port, "GET", "/metrics", bearer(BOB))
            self.assertNotIn(job.id.encode(), bobs)
            self.assertNotIn(b"alice", bobs)
            _, _, ops = request(port, "GET", "/metrics", bearer(OPERATOR))
            self.assertIn(job.id.encode(), ops)
            self.assertIn(b'erg_jobs{state="RUNNING"}', ops)
            self.assertIn(b"erg_rpc_latency_seconds", ops)
        finally:
            self.ergd.stub.CancelJob(S.CancelJobRequest(id=job.id), metadata=md(ALICE),
                                     timeout=10)
            self.ergd.wait(job.id)

    def test_sign_in_is_throttled_per_address(self):
        port = self.ergd.http_port
        wrong = form("wrong-token-0123456789")
        for i in range(10):
            self.assertEqual(request(port, "POST", "/login", *wrong, source="127.0.0.21")[0], 401,
                             i)
        status, h, _ = request(port, "POST", "/login", *wrong, source="127.0.0.21")
        self.assertEqual(status, 429)
        self.assertGreaterEqual(int(h["Retry-After"]), 1)
        # Even the right token waits now, on this address (GET links too) ...
        self.assertEqual(request(port, "POST", "/login", *form(ALICE), source="127.0.0.21")[0],
                         429)
        self.assertEqual(request(port, "GET", "/login?token=" + ALICE, source="127.0.0.21")[0],
                         429)
        # ... but not on another one.
        self.assertEqual(request(port, "POST", "/login", *form(ALICE), source="127.0.0.22")[0],
                         303)
        # Bearer requests are not sign-ins: they go on.
        self.assertEqual(request(port, "GET", "/api/jobs", bearer(ALICE), source="127.0.0.21")[0],
                         200)

    def test_cross_site_sign_in_and_sign_out_are_refused(self):
        port = self.ergd.http_port
        headers, body = form(ALICE)
        for evil in ({"Origin": "http://evil.example"}, {"Origin": "null"},
                     {"Sec-Fetch-Site": "cross-site"}, {"Sec-Fetch-Site": "same-site"},
                     {"Origin": "http://127.0.0.1:%d.evil.example" % port}):
            status, h, _ = request(port, "POST", "/login", dict(headers, **evil), body,
                                   source="127.0.0.31")
            self.assertEqual(status, 403, evil)
            self.assertIsNone(h.get("Set-Cookie"), evil)
        status, h, _ = request(port, "GET", "/login?token=" + ALICE,
                               {"Sec-Fetch-Site": "cross-site"}, source="127.0.0.31")
        self.assertEqual(status, 403)
        # Same origin, as a browser sends it from ergd's own form.
        status, h, _ = request(port, "POST", "/login",
                               dict(headers, Origin="http://127.0.0.1:%d" % port,
                                    **{"Sec-Fetch-Site": "same-origin"}), body)
        self.assertEqual(status, 303)
        cookie = session_of(h)
        # A cross-site sign-out is refused: the session lives.
        status, _, _ = request(port, "POST", "/logout",
                               {"Cookie": cookie, "Origin": "http://evil.example"}, "")
        self.assertEqual(status, 403)
        self.assertEqual(request(port, "GET", "/", {"Cookie": cookie})[0], 200)

    def test_the_session_cookie(self):
        status, h, _ = request(self.ergd.http_port, "POST", "/login", *form(ALICE))
        self.assertEqual(status, 303)
        attrs = [a.strip() for a in h["Set-Cookie"].split(";")]
        self.assertIn("HttpOnly", attrs)
        self.assertIn("SameSite=Strict", attrs)
        self.assertIn("Path=/", attrs)
        self.assertNotIn("Secure", attrs)  # plain HTTP here
        self.assertNotIn(ALICE, h["Set-Cookie"])


if __name__ == "__main__":
    unittest.main()
