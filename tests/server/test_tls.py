# SPDX-License-Identifier: Apache-2.0
"""ergd with --tls-cert/--tls-key: gRPC and HTTP over TLS with a
self-signed certificate made by the openssl CLI; plaintext is refused."""
import os
import shutil
import ssl
import subprocess
import tempfile
import unittest
import urllib.request

import grpc

from ergd_fixture import ALICE, ERGD, G, NoRedirect, S, free_port, md, self_signed_cert

OPENSSL = shutil.which("openssl")


@unittest.skipUnless(OPENSSL, "openssl CLI missing")
class Tls(unittest.TestCase):
    def test_grpc_and_http_over_tls(self):
        tmp = tempfile.mkdtemp(prefix="ergd-tls-")
        cert, key = self_signed_cert(tmp)
        with open(os.path.join(tmp, "tokens"), "w") as f:
            f.write("%s alice\n" % ALICE)
        port, hport = free_port(), free_port()
        log = open(os.path.join(tmp, "ergd.log"), "w")
        proc = subprocess.Popen([ERGD, "--listen", "127.0.0.1:%d" % port,
                                 "--http", "127.0.0.1:%d" % hport, "--data",
                                 os.path.join(tmp, "data"), "--tokens",
                                 os.path.join(tmp, "tokens"), "--tls-cert", cert,
                                 "--tls-key", key], stdout=log, stderr=subprocess.STDOUT)
        try:
            with open(cert, "rb") as f:
                creds = grpc.ssl_channel_credentials(root_certificates=f.read())
            ch = grpc.secure_channel("127.0.0.1:%d" % port, creds)
            grpc.channel_ready_future(ch).result(timeout=30)
            r = G.JobServiceStub(ch).ListJobs(S.ListJobsRequest(), metadata=md(ALICE), timeout=10)
            self.assertEqual(len(r.jobs), 0)
            # A plaintext client gets nowhere.
            plain = G.JobServiceStub(grpc.insecure_channel("127.0.0.1:%d" % port))
            with self.assertRaises(grpc.RpcError) as e:
                plain.ListJobs(S.ListJobsRequest(), metadata=md(ALICE), timeout=5)
            self.assertEqual(e.exception.code(), grpc.StatusCode.UNAVAILABLE)
            # HTTPS, with the certificate checked.
            ctx = ssl.create_default_context(cafile=cert)
            req = urllib.request.Request("https://127.0.0.1:%d/api/jobs" % hport,
                                         headers={"Authorization": "Bearer " + ALICE})
            with urllib.request.urlopen(req, context=ctx, timeout=10) as resp:
                self.assertEqual(resp.status, 200)
                self.assertEqual(resp.read().strip(), b"[]")
            login = urllib.request.Request("https://127.0.0.1:%d/login?token=%s" % (hport, ALICE))
            opener = urllib.request.build_opener(urllib.request.HTTPSHandler(context=ctx),
                                                 NoRedirect())
            with self.assertRaises(urllib.error.HTTPError) as e:
                opener.open(login, timeout=10)
            self.assertIn("Secure", e.exception.headers["Set-Cookie"])
            ch.close()
        finally:
            proc.terminate()
            proc.wait(timeout=60)
            log.close()
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    unittest.main()
