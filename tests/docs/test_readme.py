# SPDX-License-Identifier: Apache-2.0
"""README's runnable blocks (tests/docs/readme_blocks.py) run as written,
in README order in one scratch copy of the repository root, and every
```sh block of README is marked either runnable or, with its reason, not
runnable (a command a reader is shown is run here or says why not).

Command 1 (`<!-- runnable command1 -->`) is bootstrap, configure, build,
then a run: its build half is what this build tree already is (and
.ci/run's command 2 builds it), so the test runs the part after the last
`cmake --build ...` exactly as written, in the scratch root."""
import os
import re
import unittest

import readme_blocks

BUILD = os.path.dirname(os.environ["ERG_BIN_DIR"])
NOT_RUNNABLE = re.compile(r"^<!-- not runnable: .+ -->$")


def run_part(code):
    """Command 1 without its build: what follows the last `cmake --build ... &&`."""
    parts = code.strip().split(" && ")
    builds = [i for i, p in enumerate(parts) if p.startswith("cmake --build")]
    return " && ".join(parts[builds[-1] + 1:]) + "\n"


class Readme(unittest.TestCase):
    def test_every_shell_block_is_marked(self):
        with open(readme_blocks.README, encoding="utf-8") as f:
            lines = f.read().split("\n")
        unmarked = []
        inside = False
        for i, line in enumerate(lines):
            if line.startswith("```"):
                if not inside and line.strip() == "```sh":
                    j = i - 1
                    while j >= 0 and not lines[j].strip():
                        j -= 1
                    prev = lines[j].strip() if j >= 0 else ""
                    if not (readme_blocks.MARK.match(prev) or NOT_RUNNABLE.match(prev)):
                        unmarked.append(f"README.md:{i + 1}")
                inside = not inside
        self.assertEqual(unmarked, [], "```sh blocks neither runnable nor marked not runnable")

    def test_runnable_blocks_run_as_written(self):
        blocks = [b for b in readme_blocks.blocks() if b.name in (None, "command1")]
        self.assertTrue(any(b.name == "command1" for b in blocks))
        scratch = readme_blocks.Scratch(BUILD)
        scratch.env["MPLBACKEND"] = "Agg"
        try:
            for b in blocks:
                code = run_part(b.code) if b.name == "command1" else b.code
                block = readme_blocks.Block(b.name, b.lang, code, b.line)
                if b.lang == "python":
                    r = scratch.run_python(block)
                else:
                    r = scratch.run(block, timeout=900)
                self.assertEqual(r.returncode, 0, f"{b!r}:\n{code}\n{r.stdout[-2000:]}"
                                 f"{r.stderr[-3000:]}")
                print(f"{b!r}: ok")
        finally:
            scratch.cleanup()


if __name__ == "__main__":
    unittest.main()
