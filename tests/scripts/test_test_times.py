#!/usr/bin/env python3
"""Tests of scripts/test_times.py (the end of `make test`: the slowest tests of each suite and
the time of each phase): the slowest come first and are cut at --top, shares add up, a missing
file is said and is no failure. Run by ctest (tests/CMakeLists.txt)."""
import contextlib
import io
import os
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import test_times  # noqa: E402

JUNIT = """<?xml version="1.0" encoding="UTF-8"?>
<testsuite name="(empty)" tests="4">
  <testcase name="Fast.One" classname="Fast.One" time="0.5" status="run"/>
  <testcase name="Slow.Two" classname="Slow.Two" time="30" status="run"/>
  <testcase name="Mid.Three" classname="Mid.Three" time="9.5" status="run"/>
  <testcase name="Skip.Four" classname="Skip.Four" time="0" status="notrun"/>
</testsuite>
"""


def run(*argv):
    out = io.StringIO()
    sys.argv = ["test_times.py", *argv]
    with contextlib.redirect_stdout(out):
        code = test_times.main()
    return code, out.getvalue()


class TestTimes(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp()
        self.junit = os.path.join(self.dir, "junit.xml")
        with open(self.junit, "w") as f:
            f.write(JUNIT)
        self.phases = os.path.join(self.dir, "phases.tsv")
        with open(self.phases, "w") as f:
            f.write("Release: configure + build\t300\nRelease: tests\t100\n")

    def test_the_slowest_first_cut_at_top(self):
        code, out = run("--junit", "Release=" + self.junit, "--top", "2")
        self.assertEqual(code, 0)
        lines = [l for l in out.splitlines() if l.startswith("  ")]
        self.assertEqual(len(lines), 2)
        self.assertIn("Slow.Two", lines[0])
        self.assertIn("75.0%", lines[0])  # 30 of 40 s
        self.assertIn("Mid.Three", lines[1])
        self.assertIn("the 2 slowest of 4 tests of Release (40 s", out)

    def test_phases_with_their_share_and_total(self):
        code, out = run("--phases", self.phases)
        self.assertEqual(code, 0)
        self.assertIn("Release: configure + build      300 s    5.0 min  75.0%", out)
        self.assertIn("total                           400 s    6.7 min", out)

    def test_missing_files_are_said_not_failed(self):
        code, out = run("--junit", "ASan=" + os.path.join(self.dir, "none.xml"),
                        "--phases", os.path.join(self.dir, "none.tsv"))
        self.assertEqual(code, 0)
        self.assertIn("no JUnit file for ASan", out)
        self.assertIn("no phase log", out)


if __name__ == "__main__":
    unittest.main()
