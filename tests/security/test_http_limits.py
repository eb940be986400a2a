# SPDX-License-Identifier: Apache-2.0
"""HTTP that idle clients cannot starve: slow unauthenticated connections
(one header line every second, from 50 addresses, and 50 more from one
address) cost ergd no worker thread, so an authenticated /metrics answers
within 1 s while they are held; an address holds at most --http-per-address
connections; headers and bodies must arrive within --http-timeout; oversized
headers and bodies are refused."""
import socket
import threading
import time
import unittest

from ergd_fixture import OPERATOR, Ergd, ErgdTest
from sec_util import bearer, request


def slow_client(port, source):
    s = socket.socket()
    s.settimeout(5)
    s.bind((source, 0))
    s.connect(("127.0.0.1", port))
    s.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n")
    return s


def is_open(s):
    """True while ergd holds the connection: nothing to read, no EOF (what
    it says before closing one, a 408 or a 429, counts as closed)."""
    try:
        s.setblocking(False)
        s.recv(1, socket.MSG_PEEK)
        return False
    except BlockingIOError:
        return True
    except OSError:
        return False
    finally:
        s.setblocking(True)


def answer_of(s, limit=10):
    s.settimeout(limit)
    out = b""
    try:
        while True:
            chunk = s.recv(65536)
            if not chunk:
                break
            out += chunk
    except OSError:
        pass
    return out


class SlowClients(ErgdTest):
    """The defaults: 10 s to send a request, 16 connections per address."""

    def test_fifty_slow_clients_do_not_starve_metrics(self):
        port = self.ergd.http_port
        many = [slow_client(port, "127.0.0.%d" % (10 + i)) for i in range(50)]
        one = []
        for _ in range(50):  # one address: the cap closes all but 16
            try:
                one.append(slow_client(port, "127.0.0.99"))
            except OSError:
                pass
        stop = threading.Event()

        def drip():  # one more header line every second, as the attack did
            n = 0
            while not stop.wait(1.0):
                n += 1
                for s in many + one:
                    try:
                        s.sendall(b"X-Slow-%d: 1\r\n" % n)
                    except OSError:
                        pass

        t = threading.Thread(target=drip)
        t.start()
        try:
            time.sleep(2.5)  # they have each sent a few lines now
            times = []
            for _ in range(5):
                t0 = time.monotonic()
                status, _, body = request(port, "GET", "/metrics", bearer(OPERATOR), timeout=5)
                times.append(time.monotonic() - t0)
                self.assertEqual(status, 200)
                self.assertIn(b"erg_jobs", body)
            # The dashboard's sign-in page answers too.
            self.assertEqual(request(port, "GET", "/", timeout=5)[0], 401)
            print("/metrics under 100 slow connections: %s s" %
                  " ".join("%.3f" % x for x in times))
            self.assertLess(max(times), 1.0)
            # They were held, not dropped: every one of the 50 addresses, and
            # 16 from the single address (the rest were closed at once).
            self.assertEqual(sum(is_open(s) for s in many), 50)
            self.assertEqual(sum(is_open(s) for s in one), 16)
        finally:
            stop.set()
            t.join()
            for s in many + one:
                s.close()


class Deadlines(ErgdTest):
    extra_args = ("--http-timeout", "2", "--http-per-address", "4")

    def test_a_slow_request_is_cut_off_at_the_deadline(self):
        port = self.ergd.http_port
        # Slow headers, one line a second.
        s = slow_client(port, "127.0.0.2")
        t0 = time.monotonic()
        while time.monotonic() - t0 < 6 and is_open(s):
            try:
                s.sendall(b"X-Slow: 1\r\n")
            except OSError:
                break
            time.sleep(0.5)
        closed = time.monotonic() - t0
        self.assertFalse(is_open(s))
        self.assertLess(closed, 3.5)
        s.close()
        # Silent after connecting.
        s = socket.create_connection(("127.0.0.1", port), timeout=10)
        t0 = time.monotonic()
        self.assertIn(b" 408 ", answer_of(s))
        self.assertLess(time.monotonic() - t0, 3.5)
        s.close()
        # A body slower than its Content-Length.
        s = socket.create_connection(("127.0.0.1", port), timeout=10)
        s.sendall(b"POST /login HTTP/1.1\r\nHost: x\r\nContent-Length: 100\r\n\r\ntoken=")
        t0 = time.monotonic()
        self.assertIn(b" 408 ", answer_of(s))
        self.assertLess(time.monotonic() - t0, 3.5)
        s.close()

    def test_oversized_and_chunked_requests_are_refused(self):
        port = self.ergd.http_port
        cases = [(b"GET / HTTP/1.1\r\nHost: x\r\nX-Big: " + b"a" * 20000 + b"\r\n\r\n", b" 431 "),
                 (b"POST /login HTTP/1.1\r\nHost: x\r\nContent-Length: 1000000\r\n\r\n", b" 413 "),
                 # ... and while the client goes on sending the body it announced
                 # (ergd reads and drops it, so the answer is not lost to a reset).
                 (b"POST /login HTTP/1.1\r\nHost: x\r\nContent-Length: 1000000\r\n\r\n"
                  + b"t" * 300000, b" 413 "),
                 (b"POST /login HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n",
                  b" 411 "),
                 (b"POST /login HTTP/1.1\r\nHost: x\r\nContent-Length: -5\r\n\r\n", b" 400 ")]
        for raw, want in cases:
            s = socket.create_connection(("127.0.0.1", port), timeout=10)
            try:
                s.sendall(raw)
            except OSError:
                pass
            self.assertIn(want, answer_of(s)[:40], raw[:60])
            s.close()

    def test_a_client_that_expects_100_continue_gets_it(self):
        s = socket.create_connection(("127.0.0.1", self.ergd.http_port), timeout=10)
        s.sendall(b"POST /login HTTP/1.1\r\nHost: x\r\nExpect: 100-continue\r\n"
                  b"Content-Type: application/x-www-form-urlencoded\r\n"
                  b"Content-Length: 28\r\n\r\n")
        s.settimeout(1.0)
        self.assertTrue(s.recv(100).startswith(b"HTTP/1.1 100 Continue\r\n\r\n"))
        s.sendall(b"token=wrong-token-0123456789")
        self.assertIn(b" 401 ", answer_of(s))
        s.close()

    def test_the_per_address_cap(self):
        port = self.ergd.http_port
        held = [slow_client(port, "127.0.0.3") for _ in range(4)]
        extra = socket.socket()
        extra.bind(("127.0.0.3", 0))
        extra.connect(("127.0.0.1", port))
        self.assertIn(b" 429 ", answer_of(extra, 5))
        extra.close()
        # Another address is not affected, and the answer is quick.
        t0 = time.monotonic()
        self.assertEqual(request(port, "GET", "/metrics", bearer(OPERATOR), source="127.0.0.4")[0],
                         200)
        self.assertLess(time.monotonic() - t0, 1.0)
        for s in held:
            s.close()
        time.sleep(0.3)
        self.assertEqual(request(port, "GET", "/metrics", bearer(OPERATOR), source="127.0.0.3")[0],
                         200)


if __name__ == "__main__":
    unittest.main()
