# SPDX-License-Identifier: Apache-2.0
"""ergd's HTTP side: every route needs a token, /api/jobs is the tenant's,
/metrics is Prometheus text, and the dashboard, loaded in headless Chromium
(Debian's), shows the job's row and its preview image."""
import glob
import json
import os
import shutil
import subprocess
import tempfile
import unittest
import urllib.error
import urllib.parse
import urllib.request

import h5py

from ergd_fixture import ALICE, BOB, OPERATOR, ErgdTest, NoRedirect, spec_json

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"


def get(url, token=None, cookie=None, data=None):
    """GET (POST with form `data`), without following redirects."""
    req = urllib.request.Request(
        url, data=urllib.parse.urlencode(data).encode() if data is not None else None)
    if token:
        req.add_header("Authorization", "Bearer " + token)
    if cookie:
        req.add_header("Cookie", cookie)
    opener = urllib.request.build_opener(NoRedirect())
    try:
        with opener.open(req, timeout=10) as r:
            return r.status, r.read(), r.headers
    except urllib.error.HTTPError as e:
        return e.code, e.read(), e.headers


class Http(ErgdTest):
    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.job = cls.ergd.submit(spec_json(name="dune-field", steps=30, snapshot_every=10))
        cls.ergd.wait(cls.job.id)
        cls.other = cls.ergd.submit(spec_json(name="bobs", steps=2), token=BOB)
        cls.ergd.wait(cls.other.id, BOB)
        # Some RPC traffic for the latency histogram.
        cls.ergd.fetch_bytes(cls.job.id)

    def test_every_route_needs_a_token(self):
        for path in ("/", "/api/jobs", "/api/jobs/%s" % self.job.id,
                     "/api/jobs/%s/preview.png" % self.job.id, "/metrics"):
            status, _, headers = get(self.ergd.http + path)
            self.assertEqual(status, 401, path)
            self.assertIn("Bearer", headers.get("WWW-Authenticate", ""))
            self.assertEqual(get(self.ergd.http + path, "wrong-token-0123456789")[0], 401)
        self.assertEqual(get(self.ergd.http + "/login?token=wrong-token-0123456789")[0], 401)
        # The two are told apart.
        self.assertIn(b"no token", get(self.ergd.http + "/api/jobs")[1])
        self.assertIn(b"not one of ergd's tokens",
                      get(self.ergd.http + "/api/jobs", "wrong-token-0123456789")[1])

    def test_sign_in_form_posts_the_token_into_a_session_cookie(self):
        # A browser without a session gets a 401 carrying the sign-in form,
        # which POSTs the token (kept out of URLs and logs).
        status, body, headers = get(self.ergd.http + "/")
        self.assertEqual(status, 401)
        self.assertIn("Bearer", headers.get("WWW-Authenticate", ""))
        self.assertIn('<form method="post" action="/login"', body.decode())
        status, body, _ = get(self.ergd.http + "/login")
        self.assertEqual(status, 200)
        self.assertIn('type="password" name="token"', body.decode())
        # A wrong token gets no cookie.
        status, _, headers = get(self.ergd.http + "/login", data={"token": "wrong-token-0123456789"})
        self.assertEqual(status, 401)
        self.assertIsNone(headers.get("Set-Cookie"))
        # The right one: a session cookie and a 303 to the dashboard.
        status, _, headers = get(self.ergd.http + "/login", data={"token": ALICE})
        self.assertEqual(status, 303)
        self.assertEqual(headers["Location"], "/")
        cookie = headers["Set-Cookie"]
        self.assertIn("HttpOnly", cookie)
        self.assertIn("SameSite=Strict", cookie)
        self.assertNotIn("Secure", cookie)  # plain HTTP here; test_tls checks Secure
        status, body, _ = get(self.ergd.http + "/", cookie=cookie.split(";")[0])
        self.assertEqual(status, 200)
        self.assertIn('data-job="%s"' % self.job.id, body.decode())
        self.assertNotIn(self.other.id, body.decode())

    def test_api_jobs_lists_only_the_tenants_jobs(self):
        status, body, headers = get(self.ergd.http + "/api/jobs", ALICE)
        self.assertEqual(status, 200)
        self.assertIn("application/json", headers["Content-Type"])
        jobs = json.loads(body)
        ids = [j["id"] for j in jobs]
        self.assertIn(self.job.id, ids)
        self.assertNotIn(self.other.id, ids)
        mine = [j for j in jobs if j["id"] == self.job.id][0]
        self.assertEqual(mine["state"], "SUCCEEDED")
        self.assertEqual(int(mine["progress"]["step"]), 30)
        self.assertEqual(get(self.ergd.http + "/api/jobs/%s" % self.other.id, ALICE)[0], 404)
        status, png, _ = get(self.ergd.http + "/api/jobs/%s/preview.png" % self.job.id, ALICE)
        self.assertEqual(status, 200)
        self.assertEqual(png[:8], b"\x89PNG\r\n\x1a\n")

    def test_relief_is_each_snapshots_ground_range(self):
        # /api/jobs/ID/relief reads the ground range the worker reduced over
        # its tiles (root attributes ground_min_m, ground_max_m), not the
        # layers: it must equal the range of the layers themselves.
        status, body, _ = get(self.ergd.http + "/api/jobs/%s/relief" % self.job.id, ALICE)
        self.assertEqual(status, 200)
        relief = {int(r["step"]): r["relief_m"] for r in json.loads(body)}
        self.assertEqual(sorted(relief), [0, 10, 20, 30])
        files = glob.glob(os.path.join(self.ergd.data, "jobs", self.job.id, "run", "snapshots",
                                       "step_*.h5"))
        self.assertEqual(len(files), 4)
        for path in files:
            with h5py.File(path, "r") as f:
                ground = f["bedrock"][0] + f["sand"][0]  # float32, as the worker adds them
                self.assertEqual(f.attrs["ground_min_m"], float(ground.min()))
                self.assertEqual(f.attrs["ground_max_m"], float(ground.max()))
                step = int(f.attrs["step"])
            self.assertAlmostEqual(relief[step], float(ground.max()) - float(ground.min()),
                                   delta=1e-6, msg=path)
        self.assertGreater(max(relief.values()), 0)

    def test_metrics_are_prometheus_text(self):
        # An operator token reads every series (a tenant's only its own:
        # tests/security/test_http_auth.py).
        status, body, headers = get(self.ergd.http + "/metrics", OPERATOR)
        self.assertEqual(status, 200)
        text = body.decode()
        self.assertIn('erg_jobs{state="SUCCEEDED"}', text)
        self.assertIn("erg_snapshot_bytes_streamed_total", text)
        self.assertIn('erg_rpc_latency_seconds_bucket{method="GetJob"', text)
        self.assertIn('erg_rpc_latency_seconds_count{method="StreamSnapshot"}', text)
        streamed = [float(line.split()[-1]) for line in text.splitlines()
                    if line.startswith("erg_snapshot_bytes_streamed_total")]
        self.assertGreater(streamed[0], 0)

    @unittest.skipUnless(os.path.exists(CHROMIUM), "chromium is not installed")
    def test_dashboard_in_headless_chromium_shows_the_job_and_its_preview(self):
        profile = tempfile.mkdtemp(prefix="chromium-", dir=self.tmpdir)
        # /login sets the session cookie and redirects to the dashboard;
        # --dump-dom prints the DOM once the page (and its images) loaded.
        # The virtual time budget stays under the page's 5 s refresh: a
        # budget past it dumps the page while it reloads (an empty DOM). A
        # page load is retried on a loaded machine; the checks are not.
        for attempt in range(3):
            out = subprocess.run(
                [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage",
                 "--user-data-dir=" + profile + str(attempt), "--virtual-time-budget=2000",
                 "--dump-dom", self.ergd.http + "/login?token=" + ALICE],
                capture_output=True, text=True, timeout=120)
            dom = out.stdout
            if dom.strip():
                break
            print("chromium attempt %d: exit %d, empty DOM" % (attempt, out.returncode))
        self.assertIn('data-job="%s"' % self.job.id, dom, out.stderr[-2000:])
        self.assertIn("dune-field", dom)
        self.assertIn("SUCCEEDED", dom)
        self.assertNotIn(self.other.id, dom)
        # The preview <img> fired its load event: the PNG was fetched with the
        # cookie and decoded by the browser.
        img = [line for line in dom.splitlines() if "<img" in line and self.job.id in line]
        self.assertTrue(img, dom[-2000:])
        self.assertIn('data-loaded="1"', img[0])
        self.assertIn('http-equiv="refresh"', dom)


if __name__ == "__main__":
    unittest.main()
