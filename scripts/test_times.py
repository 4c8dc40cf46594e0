#!/usr/bin/env python3
"""Where `make test` and `.ci/run` spend their time (docs/robustness.md, "CI time").

    test_times.py [--phases FILE] [--junit SUITE=FILE ...] [--top N]

--phases: the phase log the Makefile appends to (one "PHASE<TAB>SECONDS" line per phase): a
table of the phases, each in seconds and as a share of the whole.
--junit: a ctest JUnit file (ctest --output-junit) for the suite SUITE: its N slowest tests
(default 20), with their share of the suite's test time.

Only reads; prints to standard output; exit 0 even when a file is missing (it says so), so that
the report never hides the result of the run it reports on.
"""
import argparse
import os
import sys
import xml.etree.ElementTree as ET


def read_phases(path):
    phases = []
    with open(path, encoding="utf-8") as f:
        for line in f:
            name, _, seconds = line.rstrip("\n").rpartition("\t")
            if name:
                phases.append((name, float(seconds)))
    return phases


def print_phases(path):
    if not os.path.isfile(path):
        print("no phase log at %s" % path)
        return
    phases = read_phases(path)
    total = sum(s for _, s in phases)
    width = max([len(n) for n, _ in phases] + [5])
    print("time of each phase (%s):" % path)
    for name, seconds in phases:
        share = 100.0 * seconds / total if total > 0 else 0.0
        print("  %-*s %8.0f s %6.1f min %5.1f%%" % (width, name, seconds, seconds / 60, share))
    print("  %-*s %8.0f s %6.1f min" % (width, "total", total, total / 60))


def print_slowest(suite, path, top):
    if not os.path.isfile(path):
        print("no JUnit file for %s at %s" % (suite, path))
        return
    cases = []
    for case in ET.parse(path).getroot().iter("testcase"):
        cases.append((float(case.get("time", "0") or 0.0), case.get("name", "?"),
                      case.get("status", "")))
    cases.sort(key=lambda c: (-c[0], c[1]))
    total = sum(t for t, _, _ in cases)
    print("the %d slowest of %d tests of %s (%.0f s of test time in all; ctest runs them in "
          "parallel):" % (min(top, len(cases)), len(cases), suite, total))
    for seconds, name, status in cases[:top]:
        note = "" if status in ("run", "") else "  (%s)" % status
        print("  %8.2f s %5.1f%%  %s%s" % (seconds, 100.0 * seconds / total if total else 0.0,
                                          name, note))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--phases")
    parser.add_argument("--junit", action="append", default=[], metavar="SUITE=FILE")
    parser.add_argument("--top", type=int, default=20)
    args = parser.parse_args()
    for item in args.junit:
        suite, _, path = item.partition("=")
        print_slowest(suite, path, args.top)
        print()
    if args.phases:
        print_phases(args.phases)
    return 0


if __name__ == "__main__":
    sys.exit(main())
