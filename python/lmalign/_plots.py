"""The plotting scripts shipped inside the package (lmalign/scripts/: plot_experiment.py,
plot_merge.py, the ones `lmalign experiment` and `lmalign merge` run), for experiment(plots=True)
and merge(plots=True).

Each script draws into a temporary folder inside the plots folder; every PNG is then written
through lmalign's one output writer (docs/robustness.md, "Outputs"), as the CLI does.
"""

import os
import subprocess
import sys
import tempfile
import warnings

from . import _lmalign


def script_path(name):
    """The packaged script `name` (e.g. 'plot_experiment.py')."""
    return os.path.join(os.path.dirname(os.path.abspath(__file__)), "scripts", name)


def draw(name, args, plots_dir):
    """Runs the packaged script `name` with `args` (with this interpreter) and writes its PNGs
    into plots_dir. Returns their paths; without matplotlib (or if the script fails) warns and
    returns []. Raises IoError when a plot cannot be written."""
    script = script_path(name)
    if not os.path.isfile(script):
        warnings.warn("no plots: %s is not installed with the package" % script, RuntimeWarning)
        return []
    _lmalign._create_output_folder(plots_dir)
    written = []
    with tempfile.TemporaryDirectory(prefix=".lmalign-plots.", dir=plots_dir) as temp:
        run = subprocess.run([sys.executable, script, *args, "--quiet", "--plots-dir", temp],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=dict(os.environ, MPLBACKEND="Agg"))
        if run.returncode != 0:
            warnings.warn("no plots: %s exited with %d: %s"
                          % (name, run.returncode, run.stderr.strip()), RuntimeWarning)
            return []
        for file in sorted(os.listdir(temp)):
            with open(os.path.join(temp, file), "rb") as f:
                data = f.read()
            path = os.path.join(plots_dir, file)
            _lmalign._write_output(path, data)
            written.append(path)
    return written
