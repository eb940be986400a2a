# SPDX-License-Identifier: Apache-2.0
"""Generates the package's protobuf and gRPC modules (erg/_proto/) from
proto/erg/v1, the one schema, with protoc and grpc_python_plugin.

protoc writes `from erg.v1 import job_pb2`; the shipped modules import
`erg._proto` instead, so the package needs no build tree and cannot collide
with another copy of the generated `erg.v1` on sys.path.

  python3 gen_stubs.py           rewrite erg/_proto/*_pb2*.py
  python3 gen_stubs.py --check   fail (exit 1, with a diff) when they differ
                                 from what proto/ generates now
"""
import argparse
import difflib
import os
import re
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
PROTO_ROOT = os.path.normpath(os.path.join(HERE, "..", "..", "proto"))
OUT = os.path.join(HERE, "erg", "_proto")
PROTOS = ["erg/v1/job.proto", "erg/v1/worker.proto", "erg/v1/service.proto"]
MODULES = ["job_pb2.py", "worker_pb2.py", "service_pb2.py", "service_pb2_grpc.py"]
HEADER = "# Generated from proto/%s by client/python/gen_stubs.py. Do not edit.\n"


def generate(protoc, plugin):
    """{module name: text} of the modules proto/ generates now."""
    with tempfile.TemporaryDirectory(prefix="erg-stubs-") as tmp:
        subprocess.run([protoc, "-I", PROTO_ROOT, "--python_out=" + tmp,
                        "--grpc_python_out=" + tmp, "--plugin=protoc-gen-grpc_python=" + plugin]
                       + PROTOS, check=True)
        out = {}
        for name in MODULES:
            with open(os.path.join(tmp, "erg", "v1", name), encoding="utf-8") as f:
                text = f.read()
            text = re.sub(r"^from erg\.v1 import ", "from erg._proto import ", text,
                          flags=re.MULTILINE)
            # The classes' __module__, so that they pickle as erg._proto.*.
            text = re.sub(r"'erg\.v1\.(\w+_pb2)'", r"'erg._proto.\1'", text)
            if "erg.v1 import" in text or "import erg.v1" in text:
                raise SystemExit("gen_stubs.py: an import of erg.v1 left in " + name)
            source = name.replace("_pb2_grpc.py", ".proto").replace("_pb2.py", ".proto")
            out[name] = HEADER % ("erg/v1/" + source) + text
        return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true")
    ap.add_argument("--protoc", default=shutil.which("protoc") or "protoc")
    ap.add_argument("--plugin", default=shutil.which("grpc_python_plugin") or "grpc_python_plugin")
    args = ap.parse_args()
    fresh = generate(args.protoc, args.plugin)
    stale = []
    for name, text in fresh.items():
        path = os.path.join(OUT, name)
        old = open(path, encoding="utf-8").read() if os.path.exists(path) else ""
        if old == text:
            continue
        if args.check:
            stale.append(name)
            sys.stdout.writelines(difflib.unified_diff(
                old.splitlines(True), text.splitlines(True), "shipped/" + name,
                "generated/" + name, n=1))
        else:
            with open(path + ".tmp", "w", encoding="utf-8") as f:
                f.write(text)
            os.replace(path + ".tmp", path)
    if stale:
        print("gen_stubs.py: client/python/erg/_proto/%s out of date with proto/; run "
              "python3 client/python/gen_stubs.py" % ", ".join(stale), file=sys.stderr)
        return 1
    print("gen_stubs.py: %d modules %s" % (len(fresh), "up to date" if args.check else "written"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
