"""Builds the Python package `lmalign` through the project's own CMake build (docs/python.md,
"Install with pip"). Run by pip or python3 -m build, not by hand:

    pip install --no-build-isolation .            # in a python3 -m venv --system-site-packages
    python3 -m build --no-isolation --wheel       # dist/lmalign-<version>-<python>-<platform>.whl

build_ext configures CMake with only the library and the module (no CLI, tests, benchmarks or map
builder), builds the target _lmalign, and installs CMake's `python` install component (the module,
__init__.py, the .pyi stubs, py.typed and the pure-Python files) into the wheel. CMake, not this
file, knows the sources and the package's files.

- The CMake build is kept in build-pip/ (or $LMALIGN_PIP_BUILD_DIR), so that a second build only
  recompiles what changed. Delete the folder to start clean.
- $CMAKE_ARGS adds CMake arguments (e.g. -DLMALIGN_BUILD_MERGE=OFF: no Ceres, no lmalign.merge).
- ccache is used when it is on PATH. $CMAKE_BUILD_PARALLEL_LEVEL sets the number of compile jobs
  (default: every core).

The version is the one in CMakeLists.txt's project(lmalign VERSION ...).
"""
import os
import re
import shlex
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent
BUILD_BASE = Path(os.environ.get("LMALIGN_PIP_BUILD_DIR") or ROOT / "build-pip").resolve()


def project_version():
    """The version of project(lmalign VERSION x.y.z) in CMakeLists.txt: the only place it is set."""
    text = (ROOT / "CMakeLists.txt").read_text(encoding="utf-8")
    match = re.search(r"project\(\s*lmalign\s+VERSION\s+([0-9]+(?:\.[0-9]+)*)", text)
    if not match:
        sys.exit("lmalign: no `project(lmalign VERSION x.y.z)` in %s" % (ROOT / "CMakeLists.txt"))
    return match.group(1)


def _include_dirs():
    dirs = [Path(sysconfig.get_paths()["include"]), Path("/usr/include"), Path("/usr/local/include")]
    for var in ("CPATH", "CPLUS_INCLUDE_PATH"):
        dirs += [Path(d) for d in os.environ.get(var, "").split(os.pathsep) if d]
    dirs += [Path(d) / "include" for d in
             os.environ.get("CMAKE_PREFIX_PATH", "").split(os.pathsep) if d]
    return dirs


def _has_header(name):
    return any((d / name).is_file() for d in _include_dirs())


def _has_module(name):
    try:
        __import__(name)
        return True
    except ImportError:
        return False


def missing_debian_packages(need_wheel):
    """The Debian packages (bookworm names) of what building the module needs and this machine
    lacks, judged by what each package provides (a program on PATH, a header), so that the same
    things installed another way also count. `make deps` installs them all."""
    cxx = shlex.split(os.environ.get("CXX", "")) or ["c++"]
    checks = [
        ("cmake", shutil.which("cmake")),
        ("g++", shutil.which(cxx[0]) or shutil.which("g++")),
        ("make", os.environ.get("CMAKE_GENERATOR") or shutil.which("make")),
        ("python3-dev", _has_header("Python.h")),
        ("libeigen3-dev", _has_header("eigen3/Eigen/Core")),
        ("libyaml-cpp-dev", _has_header("yaml-cpp/yaml.h")),
        ("nlohmann-json3-dev", _has_header("nlohmann/json.hpp")),
        ("pybind11-dev", _has_header("pybind11/pybind11.h")),
        ("python3-numpy", _has_module("numpy")),
    ]
    if need_wheel:
        checks.append(("python3-wheel", _has_module("wheel")))
    return [package for package, found in checks if not found]


def require_build_dependencies():
    """Stops with one message naming the missing Debian packages, before anything is built."""
    missing = missing_debian_packages(need_wheel="bdist_wheel" in sys.argv)
    if missing:
        sys.exit("lmalign: cannot build the Python package: missing Debian packages: %s. "
                 "Install them (apt-get install %s, or `make deps` in the lmalign checkout), "
                 "then run the same command again." % (" ".join(missing), " ".join(missing)))


class CMakeBuild(build_ext):
    """Builds and installs the module with CMake instead of compiling the Extension's sources."""

    def run(self):
        if self.inplace or getattr(self, "editable_mode", False):
            sys.exit("lmalign: editable installs (pip install -e) are not supported; use "
                     "`make build` and PYTHONPATH=build/python (docs/python.md)")
        require_build_dependencies()
        cmake_dir = Path(self.build_temp).resolve() / "cmake"
        cache = cmake_dir / "CMakeCache.txt"
        if cache.is_file() and "CMAKE_HOME_DIRECTORY:INTERNAL=%s\n" % ROOT not in cache.read_text():
            shutil.rmtree(cmake_dir)  # a build of another source folder (e.g. an unpacked sdist)
        package_dir = Path(self.build_lib).resolve() / "lmalign"
        user_args = shlex.split(os.environ.get("CMAKE_ARGS", ""))
        configure = [
            "cmake", "-S", str(ROOT), "-B", str(cmake_dir),
            "-DCMAKE_BUILD_TYPE=Release",
            "-DPython3_EXECUTABLE=" + sys.executable,
            "-DLMALIGN_BUILD_PYTHON=ON",
            "-DLMALIGN_BUILD_TESTS=OFF", "-DLMALIGN_BUILD_APPS=OFF", "-DLMALIGN_BUILD_VO=OFF",
            "-DLMALIGN_BUILD_BENCH=OFF", "-DLMALIGN_WITH_PCL=OFF", "-DLMALIGN_WITH_OPEN3D=OFF",
            # relative to the --prefix of the install below: <build_lib>/lmalign
            "-DLMALIGN_PYTHON_INSTALL_DIR=.",
        ]
        if shutil.which("ccache") and not any("COMPILER_LAUNCHER" in a for a in user_args):
            configure.append("-DCMAKE_CXX_COMPILER_LAUNCHER=ccache")
        self._run(configure + user_args)
        build = ["cmake", "--build", str(cmake_dir), "--target", "_lmalign"]
        if not os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL"):
            build += ["-j", str(os.cpu_count() or 2)]
        self._run(build)
        # Only what CMake installs now: nothing left from an earlier build of another version.
        shutil.rmtree(package_dir, ignore_errors=True)
        self._run(["cmake", "--install", str(cmake_dir), "--component", "python",
                   "--prefix", str(package_dir.parent)])

    @staticmethod
    def _run(command):
        line = " ".join(shlex.quote(c) for c in command)
        print("lmalign:", line, flush=True)
        code = subprocess.run(command).returncode
        if code != 0:
            sys.exit("lmalign: failed (exit %d), see the output above: %s" % (code, line))


if any(c in sys.argv for c in ("dist_info", "build", "build_ext", "bdist_wheel", "install")):
    # Before setuptools runs: without python3-wheel, bdist_wheel would fail as an unknown command.
    # dist_info: pip prepares the metadata before it looks for the dependencies (numpy), so
    # that a machine without them gets this message rather than pip's "no matching distribution".
    require_build_dependencies()

BUILD_BASE.mkdir(parents=True, exist_ok=True)  # egg_info writes lmalign.egg-info there
setup(
    version=project_version(),
    # No packages for setuptools to copy: CMake installs the whole package (build_ext above).
    packages=[],
    py_modules=[],
    ext_modules=[Extension("lmalign._lmalign", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    options={"build": {"build_base": str(BUILD_BASE)},
             "egg_info": {"egg_base": str(BUILD_BASE)}},
    zip_safe=False,
)
