# SPDX-License-Identifier: Apache-2.0
"""The dashboard in headless Chromium (Debian's chromium and
chromium-driver, driven by Selenium) against a real ergd with real
workers: the list's state filters, a click to a job's page with its full
preview, a slider over the snapshots, the three plots and the event log;
steering and cancelling a running job with the page's buttons; another
tenant's job page is NOT_FOUND. Every asset comes from ergd (the page is
checked for any other origin). Screenshots go to $ERG_SCREENSHOT_DIR (README
shows the ones in docs/), else to the test's directory."""
import os
import shutil
import tempfile
import time
import unittest
import urllib.error
import urllib.request

from ergd_fixture import ALICE, BOB, ErgdTest, spec_json

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
DRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"
try:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys
    from selenium.webdriver.support.ui import WebDriverWait
    HAVE_SELENIUM = True
except ImportError:
    HAVE_SELENIUM = False


@unittest.skipUnless(HAVE_SELENIUM and os.path.exists(DRIVER) and os.path.exists(CHROMIUM),
                     "chromium-driver and python3-selenium are not installed (deploy/bootstrap.sh)")
class Dashboard(ErgdTest):
    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.done = cls.ergd.submit(spec_json(nx=128, ny=96, steps=240, snapshot_every=40,
                                             name="dune-field"))
        cls.ergd.wait(cls.done.id)
        cls.running = cls.ergd.submit(spec_json(nx=128, ny=96, steps=1000000, snapshot_every=50,
                                                checkpoint_every=0, name="long-run"))
        cls.ergd.wait(cls.running.id, until=lambda j: j.progress.latest_snapshot_step >= 50)
        cls.shots = os.environ.get("ERG_SCREENSHOT_DIR") or tempfile.mkdtemp(dir=cls.tmpdir)
        opts = webdriver.ChromeOptions()
        opts.binary_location = CHROMIUM
        for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                  "--window-size=1100,1500", "--disable-background-networking",
                  "--disable-component-update", "--no-first-run"):
            opts.add_argument(a)
        cls.browser = webdriver.Chrome(service=Service(DRIVER), options=opts)
        cls.browser.set_page_load_timeout(60)
        cls.wait = WebDriverWait(cls.browser, 60)

    @classmethod
    def tearDownClass(cls):
        cls.browser.quit()
        super().tearDownClass()

    def open(self, path):
        self.browser.get(self.ergd.http + path)

    def assertOnlyErgdAssets(self):
        origin = self.ergd.http
        urls = self.browser.execute_script(
            "return performance.getEntriesByType('resource').map(e => e.name)")
        self.assertTrue(urls)
        self.assertEqual([u for u in urls if not u.startswith(origin)], [])

    def job_page_ready(self):
        self.wait.until(lambda b: b.find_element(By.TAG_NAME, "body").get_attribute("data-ready"))
        self.wait.until(lambda b: b.find_element(By.ID, "preview").get_attribute("data-loaded"))

    def test_1_list_filters_and_a_click_to_the_job_page(self):
        self.open("/login?token=" + ALICE)
        rows = self.browser.find_elements(By.CSS_SELECTOR, "tr.job")
        self.assertEqual({r.get_attribute("data-job") for r in rows},
                         {self.done.id, self.running.id})
        self.browser.find_element(By.LINK_TEXT, "running").click()
        rows = self.browser.find_elements(By.CSS_SELECTOR, "tr.job")
        self.assertEqual([r.get_attribute("data-job") for r in rows], [self.running.id])
        self.browser.find_element(By.LINK_TEXT, "succeeded").click()
        rows = self.browser.find_elements(By.CSS_SELECTOR, "tr.job")
        self.assertEqual([r.get_attribute("data-job") for r in rows], [self.done.id])
        self.browser.find_element(By.LINK_TEXT, "all").click()
        # Simulated years beside the steps: 240 steps x the default 10 days.
        done_row = self.browser.find_element(By.CSS_SELECTOR, 'tr.job[data-job="%s"]' % self.done.id)
        self.assertEqual(done_row.find_element(By.CLASS_NAME, "years").text, "6.57 years")
        self.browser.save_screenshot(os.path.join(self.shots, "dashboard-list.png"))
        self.browser.find_element(By.LINK_TEXT, self.done.id).click()
        self.job_page_ready()
        self.assertIn("/jobs/" + self.done.id, self.browser.current_url)
        img = self.browser.find_element(By.ID, "preview")
        # Full size: the worker's labelled preview (128 cells at 6 px each),
        # the same PNG erg preview fetches, not a thumbnail.
        self.assertEqual(self.browser.execute_script("return arguments[0].naturalWidth", img), 768)
        self.assertGreaterEqual(img.size["width"], 768)
        self.assertEqual(self.browser.find_element(By.ID, "preview-caption").text, "step 240")
        self.assertEqual(self.browser.find_element(By.ID, "state").text, "SUCCEEDED")
        self.assertRegex(self.browser.find_element(By.ID, "summary").text,
                         r"^step 240 of 240 \(6\.6 simulated years\)")
        # Three plots with a line each, drawn from the progress events.
        for pid in ("plot-rate", "plot-relief", "plot-flux"):
            lines = self.browser.find_elements(By.CSS_SELECTOR, "#%s polyline" % pid)
            self.assertEqual(len(lines), 1, pid)
            self.assertGreater(len(lines[0].get_attribute("points").split()), 1, pid)
        events = self.browser.find_element(By.ID, "events").text
        self.assertIn("snapshot at step 240", events)
        self.assertIn("state SUCCEEDED", events)
        # A finished job offers no controls.
        self.assertFalse(self.browser.find_element(By.ID, "cancel").is_enabled())
        self.browser.save_screenshot(os.path.join(self.shots, "dashboard-job.png"))
        # The slider: to the first snapshot, then one step right.
        slider = self.browser.find_element(By.ID, "slider")
        slider.send_keys(Keys.HOME)
        self.wait.until(lambda b: b.find_element(By.ID, "preview-caption").text == "step 0")
        self.wait.until(lambda b: b.find_element(By.ID, "preview").get_attribute("data-loaded"))
        slider.send_keys(Keys.ARROW_RIGHT)
        self.wait.until(lambda b: b.find_element(By.ID, "preview-caption").text == "step 40")
        self.wait.until(lambda b: b.find_element(By.ID, "preview").get_attribute("data-loaded"))
        self.assertTrue(self.browser.find_element(By.ID, "preview").get_attribute("src")
                        .endswith("preview.png?step=40"))
        self.assertOnlyErgdAssets()

    def test_2_steer_then_cancel_a_running_job(self):
        self.open("/login?token=" + ALICE)
        self.open("/jobs/" + self.running.id)
        self.job_page_ready()
        self.wait.until(lambda b: b.find_element(By.ID, "state").text == "RUNNING")
        box = self.browser.find_element(By.ID, "steer-event")
        box.clear()
        box.send_keys('{"sand": {"x_m": 30, "y_m": 30, "radius_m": 8, "height": 2}}')
        self.browser.find_element(By.ID, "steer").click()
        self.wait.until(lambda b: b.find_element(By.ID, "control-result").text.startswith("applied"))
        self.wait.until(lambda b: "steered at step" in b.find_element(By.ID, "events").text)
        # A bad event is refused with the reason, and the job goes on.
        box.clear()
        box.send_keys('{"sand": {"radius_m": -1}}')
        self.browser.find_element(By.ID, "steer").click()
        self.wait.until(lambda b: "refused" in b.find_element(By.ID, "control-result").text)
        self.browser.find_element(By.ID, "cancel").click()
        self.wait.until(lambda b: b.find_element(By.ID, "state").text == "CANCELLED")
        self.assertIn("state CANCELLED", self.browser.find_element(By.ID, "events").text)
        self.assertEqual(self.ergd.get(self.running.id).state, 5)  # JOB_STATE_CANCELLED
        self.assertOnlyErgdAssets()

    def test_3_another_tenants_job_page_is_not_found(self):
        for path in ("/jobs/%s" % self.done.id, "/api/jobs/%s/events" % self.done.id,
                     "/api/jobs/%s/relief" % self.done.id):
            req = urllib.request.Request(self.ergd.http + path,
                                         headers={"Authorization": "Bearer " + BOB})
            with self.assertRaises(urllib.error.HTTPError) as e:
                urllib.request.urlopen(req, timeout=10)
            self.assertEqual(e.exception.code, 404, path)
        req = urllib.request.Request(self.ergd.http + "/api/jobs/%s/cancel" % self.done.id,
                                     data=b"", headers={"Authorization": "Bearer " + BOB})
        with self.assertRaises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(req, timeout=10)
        self.assertEqual(e.exception.code, 404)


if __name__ == "__main__":
    unittest.main()
