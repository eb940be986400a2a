# SPDX-License-Identifier: Apache-2.0
"""README's ergd quick start, run exactly as README writes it (the blocks
marked `<!-- runnable quickstart -->`) against the real ergd it starts on
the default ports 127.0.0.1:7117 and 7118 (ctest holds a resource lock on
them). Between its two parts (start, submit, watch, fetch; then stop) the
test checks what the reader is told to look at: the fetched snapshot, the
token file, and the dashboard link, which signs in and lists the job."""
import http.cookiejar
import os
import re
import stat
import time
import unittest
import urllib.request

import readme_blocks

BUILD = os.path.dirname(os.environ["ERG_BIN_DIR"])


class Quickstart(unittest.TestCase):
    def test_quickstart_as_written(self):
        parts = [b for b in readme_blocks.blocks() if b.name == "quickstart"]
        self.assertEqual(len(parts), 2, "README has the quick start in two parts (start, stop)")
        scratch = readme_blocks.Scratch(BUILD)
        session = readme_blocks.Session(scratch)
        try:
            out = session.part(parts[0], timeout=900)
            log = session.stderr()
            # erg fetch printed the path it wrote; erg watch saw the job end.
            fetched = [l for l in out.split("\n") if l.endswith(".h5")]
            self.assertEqual(len(fetched), 1, out + log)
            self.assertTrue(os.path.isfile(scratch.path(fetched[0])), fetched)
            self.assertIn("SUCCEEDED", log.upper())
            tokens = scratch.path("ergd-home", "tokens")
            self.assertEqual(stat.S_IMODE(os.stat(tokens).st_mode), 0o600)
            # The dashboard link signs in (a session cookie) and shows the job.
            m = re.search(r"(http://127\.0\.0\.1:7118/\S+)", out)
            self.assertIsNotNone(m, out)
            jar = http.cookiejar.CookieJar()
            opener = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(jar))
            with opener.open(m.group(1), timeout=10) as r:
                page = r.read().decode()
            self.assertTrue(any(c.name == "erg_session" for c in jar), page[:500])
            with opener.open("http://127.0.0.1:7118/api/jobs", timeout=10) as r:
                jobs = r.read().decode()
            self.assertIn('"tenant":"demo","state":"SUCCEEDED"', jobs)
            session.part(parts[1], timeout=120)
            # ergd stopped: its port is free again.
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline:
                try:
                    urllib.request.urlopen("http://127.0.0.1:7118/", timeout=1)
                except urllib.error.URLError as e:
                    if isinstance(e.reason, ConnectionRefusedError):
                        break
                except Exception:
                    pass
                time.sleep(0.2)
            else:
                self.fail("ergd still answers after the quick start's stop")
        finally:
            session.close()
            scratch.cleanup()


if __name__ == "__main__":
    unittest.main()
