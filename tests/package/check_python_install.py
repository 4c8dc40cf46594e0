"""Checks an installed Python package lmalign from outside the repository: run by
python_package_test.py (pip, wheel) and deb_package_test.py with the interpreter under test, from
an empty folder.

    check_python_install.py --prefix DIR --version V [--metadata] [--data DIR]

- `import lmalign` finds the copy under DIR, with its stubs (__init__.pyi, py.typed);
- lmalign.__version__ is V, and with --metadata so is the installed distribution's version;
- with --data, it aligns the real TUM fr1/desk pair (the truth is the identity), displaced by
  the paper's Table 1 pose, with the recommended strategy, and checks the result against the
  truth, then runs a small protocol on it with lmalign.experiment(plots=True): the plots come
  from the script inside the installed package (when the interpreter has matplotlib). Exit
  code 77 (after every other check passed) when the data is missing.
"""
import argparse
import ast
import importlib.metadata
import math
import pathlib
import sys

import numpy as np

import lmalign

SKIP = 77

parser = argparse.ArgumentParser()
parser.add_argument("--prefix", required=True)
parser.add_argument("--version", required=True)
parser.add_argument("--metadata", action="store_true")
parser.add_argument("--data")
args = parser.parse_args()

package = pathlib.Path(lmalign.__file__).resolve().parent
prefix = pathlib.Path(args.prefix).resolve()
assert prefix in package.parents, "lmalign imported from %s, not from %s" % (package, prefix)
assert lmalign.__version__ == args.version, (lmalign.__version__, args.version)
if args.metadata:
    assert importlib.metadata.version("lmalign") == args.version, importlib.metadata.version(
        "lmalign")
stub = package / "__init__.pyi"
assert (package / "py.typed").is_file(), "py.typed missing in %s" % package
stub_names = {node.name for node in ast.walk(ast.parse(stub.read_text()))
              if isinstance(node, (ast.FunctionDef, ast.ClassDef))}
assert {"align", "read_map", "AlignmentResult"} <= stub_names, sorted(stub_names)
print("lmalign %s from %s (stubs: %d names)" % (lmalign.__version__, package, len(stub_names)))

# Arrays in, arrays out: a known shift recovered exactly.
target = np.random.default_rng(1).uniform(-1.0, 1.0, size=(200, 3))
result = lmalign.align(target + [0.01, 0.0, 0.0], target, strategy="base")
assert np.allclose(result.T_target_source[:3, 3], [-0.01, 0.0, 0.0], atol=1e-9), result

if not args.data:
    sys.exit(0)
pair = pathlib.Path(args.data) / "tum_fr1_desk" / "ground_truth_pair"
paths = [pair / "desk_gt_a.txt", pair / "desk_gt_b.txt"]
if not all(p.is_file() for p in paths):
    print("real data not found: %s (set LMALIGN_DATA)" % pair)
    sys.exit(SKIP)
source, target = (lmalign.read_map(p) for p in paths)
# The source moved by the paper's Table 1 pose; the truth is then T_target_source = inverse(T).
T = lmalign.pose_from_xyz_rpy_deg(0, 1, 0.4, 10, 0, 22.5)
result = lmalign.align(source.transformed(T), target)  # the recommended strategy
error = result.T_target_source @ T  # identity when the alignment is right
rotation_deg = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(error[:3, :3]) - 1) / 2))))
translation_m = float(np.linalg.norm(error[:3, 3]))
print("desk pair, %s: %.3f deg, %.4f m from the truth; trustworthy %s"
      % (result.strategy, rotation_deg, translation_m, result.trustworthy))
# The truth itself is known to about 0.7 deg and 1 cm (docs/method.md section 6).
assert result.trustworthy, result.trust_reason
assert rotation_deg < 2.0 and translation_m < 0.05, (rotation_deg, translation_m)

# The plots of the protocol, drawn by the script shipped inside the installed package.
try:
    import matplotlib  # noqa: F401
except ImportError:
    print("no matplotlib for %s: the packaged plots are not checked" % sys.executable)
    sys.exit(0)
import tempfile

from lmalign import _plots

assert prefix in pathlib.Path(_plots.script_path("plot_experiment.py")).resolve().parents
with tempfile.TemporaryDirectory() as out:
    config = pathlib.Path(out) / "protocol.yaml"
    config.write_text("source: %s\ntarget: %s\nground_truth: identity\nstrategies: [base]\n"
                      "experiments:\n  - {name: yaws, type: yaw, yaw_deg: [0, 10]}\n"
                      % tuple(paths))
    report = lmalign.experiment(config, pathlib.Path(out) / "report", plots=True)
    names = sorted(pathlib.Path(p).name for p in report["plots"])
    assert "yaws_violin.png" in names, names
    print("plots from the installed package:", ", ".join(names))
