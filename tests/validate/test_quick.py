# SPDX-License-Identifier: Apache-2.0
"""erg validate --quick as a user runs it: the report exists with every
section, each section has numbers and a verdict, the plots it links exist,
the mass law passes exactly (sand is conserved to the unit in every scene),
and every law the quick scenes are built to show (thresholds.json
"quick_laws") passes: the test fails when any of them fails. The other laws
need mature dunes the quick scenes are too short to grow; the report gives
their verdict and measured cause."""
import os
import re
import subprocess
import tempfile
import unittest
from pathlib import Path

ERG = os.environ["ERG_BIN"]
SECTIONS = [
    "## 1. Barchan migration speed against height",
    "## 2. Barchan shape",
    "## 3. Slip faces",
    "## 4. Transverse dunes",
    "## 5. Mass",
    "## 6. Migration rate in physical units",
    "## 7. Flat-bed flux against the flux law",
    "## 8. Wind-rose drift: DP, RDP, RDD",
]

VERDICTS = ("PASS", "FAIL", "UNRESOLVED", "NOT RUN")


def summary_of(report):
    """The report's summary table: law -> [verdict, measured]."""
    summary = {}
    for line in report.split("\n## ")[0].splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and cells[1] in VERDICTS:
            summary[cells[0]] = cells[1:]
    return summary


class Quick(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.out = Path(cls.tmp.name) / "validation"
        cls.proc = subprocess.run([ERG, "validate", "--out", str(cls.out), "--quick"],
                                  capture_output=True, text=True, timeout=400)
        cls.report = (cls.out / "report.md").read_text() if (cls.out / "report.md").exists() else ""

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_runs_and_reports_progress(self):
        self.assertEqual(self.proc.returncode, 0, self.proc.stderr[-3000:])
        self.assertIn("erg validate: [1/3]", self.proc.stderr)
        self.assertRegex(self.proc.stderr, r"\d+ of \d+ laws pass; report in ")

    def test_every_section_with_numbers_and_verdict(self):
        parts = re.split(r"(?m)^(?=## )", self.report)
        body = {p.splitlines()[0]: p for p in parts if p.startswith("## ")}
        self.assertEqual(list(body), SECTIONS)
        for title, text in body.items():
            # A table of measured values: some cell holds a number.
            self.assertRegex(text, r"\| [-+]?\d+(\.\d+)? \|", title + ": no measured number")
            self.assertRegex(text, r"\*\*(PASS|FAIL|UNRESOLVED)\*\*", title + ": no verdict")
            self.assertIn("Source: ", text, title + ": no source")
        self.assertRegex(self.report, r"\*\*\d+ of \d+ laws pass\.\*\*")

    def test_model_unit_beds_carry_their_caveat(self):
        # The quick transverse scenes are in model units, the barchans in
        # physical ones: only the transverse section says that its pattern
        # depends on the slab, and it names those scenes.
        parts = re.split(r"(?m)^(?=## )", self.report)
        body = {p.splitlines()[0]: p for p in parts if p.startswith("## ")}
        transverse = body["## 4. Transverse dunes"]
        self.assertIn("**Model units:**", transverse)
        for name in ("validate-transverse-2m-quick", "validate-transverse-1m-quick"):
            self.assertIn(name, transverse.split("**Model units:**")[1].split(" are in model units")[0])
        others = [t for title, t in body.items() if title != "## 4. Transverse dunes"]
        self.assertFalse(any("**Model units:**" in t for t in others))

    def test_mass_law_passes_exactly(self):
        mass = self.report.split("## 5. Mass")[1].split("\n## ")[0]
        rows = [l for l in mass.splitlines() if l.startswith("| validate-")]
        self.assertEqual(len(rows), 3)
        for row in rows:
            # scene | snapshots | intervals checked | total at 0 | at end | drift | events
            cells = [c.strip() for c in row.strip().strip("|").split("|")]
            self.assertEqual(int(cells[2]), int(cells[1]) - 1, row)
            self.assertEqual(cells[3], cells[4], row)
            self.assertEqual(cells[5], "0", row)
            self.assertEqual(cells[6], "0", row)
        # And from the snapshots themselves, independently of the report.
        import h5py
        for run in sorted((self.out / "runs").iterdir()):
            if not run.is_dir():
                continue
            totals = set()
            files = sorted((run / "snapshots").glob("step_*.h5"))
            self.assertGreaterEqual(len(files), 3, run)
            for f in files:
                with h5py.File(f, "r") as h:
                    a = h.attrs
                    totals.add(int(str(a["sand_units_total"].decode() if isinstance(
                        a["sand_units_total"], bytes) else a["sand_units_total"])) + int(str(
                        a["airborne_units_total"].decode() if isinstance(
                            a["airborne_units_total"], bytes) else a["airborne_units_total"])))
            self.assertEqual(len(totals), 1, f"{run.name}: totals {totals}")
        self.assertIn("Expected drift: 0 units. **PASS**", mass)
        self.assertRegex(self.report, r"\| Mass conserved exactly \| PASS \| exact \|")

    def test_laws_the_quick_scenes_show_pass(self):
        import json
        src = Path(os.environ["ERG_SOURCE_DIR"]) / "client" / "validate" / "thresholds.json"
        laws = json.loads(src.read_text())["quick_laws"]["laws"]
        summary = summary_of(self.report)
        for law in laws:
            self.assertIn(law, summary, f"law '{law}' missing from the summary")
            self.assertEqual(summary[law][0], "PASS", f"{law}: {summary[law][1]}")

    def test_plots_exist(self):
        for png in re.findall(r"\]\((plots/[a-z_]+\.png)\)", self.report):
            p = self.out / png
            self.assertTrue(p.exists(), png)
            self.assertEqual(p.read_bytes()[:8], b"\x89PNG\r\n\x1a\n")
        self.assertGreaterEqual(len(re.findall(r"\]\(plots/", self.report)), 5)

    def test_usage_errors(self):
        p = subprocess.run([ERG, "validate"], capture_output=True, text=True, timeout=30)
        self.assertEqual(p.returncode, 2)
        self.assertIn("--out DIR is required", p.stderr)
        self.assertIn("erg validate --out DIR [--quick]", p.stderr)
        # An existing run is never overwritten without --reuse.
        p = subprocess.run([ERG, "validate", "--out", str(self.out), "--quick"],
                           capture_output=True, text=True, timeout=30)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("exists; choose a new --out or pass --reuse", p.stderr)

    def test_skipped_scenes_leave_their_laws_not_run(self):
        """--skip leaves scenes out (the full suite's largest take hours): every
        law that needs one reads NOT RUN, never PASS on the scenes that ran,
        and the others are judged as in a whole run."""
        import shutil
        out = Path(self.tmp.name) / "skipped"
        shutil.copytree(self.out / "runs", out / "runs")
        p = subprocess.run([ERG, "validate", "--out", str(out), "--quick", "--reuse",
                            "--skip", "transverse_fine"], capture_output=True, text=True, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr[-3000:])
        self.assertIn("[1/2]", p.stderr)
        self.assertNotIn("validate-transverse-1m-quick", p.stderr)
        report = (out / "report.md").read_text()
        summary = summary_of(report)
        full = summary_of(self.report)
        self.assertNotIn("NOT RUN", [v for v, _ in full.values()])
        self.assertEqual(set(summary), set(full))
        needs_fine = ("Slip faces at repose", "Transverse crests perpendicular",
                      "Transverse wavelength resolution-independent")
        for law, (result, measured) in summary.items():
            if law in needs_fine:
                self.assertEqual(result, "NOT RUN", law)
                self.assertIn("not run: validate-transverse-1m-quick", measured)
            else:
                self.assertEqual([result, measured], full[law], law)
        self.assertRegex(report, r"3 NOT RUN: their scenes were left out of this invocation "
                                 r"\(--skip: validate-transverse-1m-quick\)")
        transverse = report.split("## 4. Transverse dunes")[1].split("\n## ")[0]
        self.assertIn("Transverse wavelength resolution-independent: **NOT RUN**", transverse)
        # A pattern that names no scene is an error, not a silent full run.
        p = subprocess.run([ERG, "validate", "--out", str(out), "--quick", "--reuse",
                            "--skip", "transverse_finer"], capture_output=True, text=True, timeout=60)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--skip transverse_finer matches no scene", p.stderr)

    def test_barchans_in_both_transport_modes(self):
        """A suite with barchans_expected (the full one) measures the barchan
        laws in each mode: one section each, a part per mode, the laws named
        with their mode, the plots apart. Here on the quick scenes plus an
        EXPECTED twin of their barchans (a coarser step: a few seconds)."""
        import json
        import shutil
        scenes = Path(self.tmp.name) / "scenes"
        shutil.copytree(Path(os.environ["ERG_SOURCE_DIR"]) / "client/validate/scenes/quick", scenes)
        job = json.loads((scenes / "barchans.json").read_text())
        job.update(name="validate-barchans-quick-expected", transport="EXPECTED")
        job["model"]["slab_m"] *= 4
        job["run"].update(steps=job["run"]["steps"] // 4, snapshot_every=job["run"]["snapshot_every"] // 4)
        (scenes / "barchans_expected.json").write_text(json.dumps(job))
        out = Path(self.tmp.name) / "both"
        shutil.copytree(self.out / "runs", out / "runs")
        p = subprocess.run([ERG, "validate", "--out", str(out), "--quick", "--reuse", "--scenes", str(scenes)],
                           capture_output=True, text=True, timeout=300)
        self.assertEqual(p.returncode, 0, p.stderr[-3000:])
        report = (out / "report.md").read_text()
        laws = summary_of(report)
        for law in ("Barchan speed c = a Q / (H + H0)", "Barchan H/W ~ 0.1, horns downwind",
                    "Migration rate against Tarfaya"):
            self.assertIn(f"{law} (STOCHASTIC)", laws)
            self.assertIn(f"{law} (EXPECTED)", laws)
            self.assertNotIn(law, laws)
        parts = re.split(r"(?m)^(?=## )", report)
        heads = [q.splitlines()[0] for q in parts if q.startswith("## ")]
        self.assertEqual(heads, SECTIONS)
        for title in (SECTIONS[0], SECTIONS[1], SECTIONS[5]):
            text = report.split(title)[1].split("\n## ")[0]
            self.assertLess(text.index("**STOCHASTIC transport** (scene `validate-barchans-quick`)"),
                            text.index("**EXPECTED transport** (scene `validate-barchans-quick-expected`)"))
        for png in ("barchan_speed", "barchans", "migration_rate"):
            self.assertTrue((out / "plots" / f"{png}.png").exists(), png)
            self.assertTrue((out / "plots" / f"{png}_expected.png").exists(), png)
        # The STOCHASTIC barchans are measured as in the quick suite itself.
        rows = [l for l in self.report.split("\n## ")[0].splitlines()
                if l.startswith("| Barchan") or l.startswith("| Migration")]
        self.assertEqual(len(rows), 3)
        for line in rows:
            self.assertIn("(STOCHASTIC) |", line)
            self.assertIn(line, report)

    def test_thresholds_have_sources(self):
        import json
        src = Path(os.environ["ERG_SOURCE_DIR"]) / "client" / "validate" / "thresholds.json"
        T = json.loads(src.read_text())
        for law in ("barchan_speed", "barchan_shape", "slip_face", "transverse", "migration_rate",
                    "mass", "flux_law", "drift"):
            self.assertIn("source", T[law], law)


if __name__ == "__main__":
    unittest.main()
