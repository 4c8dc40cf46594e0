"""Run by run_package_test.cmake from a folder outside the repository, with PYTHONPATH set to the
installed package only: `import lmalign` must find the installed copy, and it must work."""
import sys

import numpy as np

import lmalign

prefix = sys.argv[1]
assert lmalign.__file__.startswith(prefix), (lmalign.__file__, prefix)
target = np.random.default_rng(1).uniform(-1.0, 1.0, size=(200, 3))
result = lmalign.align(target + [0.01, 0.0, 0.0], target, strategy="base")
assert np.allclose(result.T_target_source[:3, 3], [-0.01, 0.0, 0.0], atol=1e-9), result
print("python:", lmalign.__file__, result)
