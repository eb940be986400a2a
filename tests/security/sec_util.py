# SPDX-License-Identifier: Apache-2.0
"""Helpers of the security tests: raw HTTP from a chosen loopback source
address (the whole of 127.0.0.0/8 is loopback on Linux, so one machine can
play many clients), and the tokens file rewritten as an operator would."""
import http.client
import os
import time

from ergd_fixture import ALICE, BOB, CAROL, OPERATOR

STANDARD_TOKENS = "# test tokens\n%s alice\n%s bob\n%s carol\n%s ops operator\n" % (
    ALICE, BOB, CAROL, OPERATOR)


def write_tokens(path, text, atomic=True):
    """Replaces the tokens file (atomically by default, as `mv` would) and
    waits past ergd's 100 ms between checks."""
    if atomic:
        tmp = path + ".new"
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    else:
        with open(path, "w") as f:
            f.write(text)
    time.sleep(0.15)


def request(port, method, path, headers=None, body=None, source="127.0.0.1", timeout=10):
    """(status, headers, body) of one HTTP request from `source`."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout,
                                      source_address=(source, 0))
    try:
        conn.request(method, path, body=body, headers=headers or {})
        r = conn.getresponse()
        return r.status, r.headers, r.read()
    finally:
        conn.close()


def bearer(token):
    return {"Authorization": "Bearer " + token}


def form(token):
    return {"Content-Type": "application/x-www-form-urlencoded"}, "token=" + token


def session_of(headers):
    """The `erg_session=ID` pair of a Set-Cookie header."""
    return headers["Set-Cookie"].split(";")[0]
