"""ctest Package.PythonWheel and Package.PipInstall: the Python package installed the ways a user
installs it, offline, with Debian's tools only (docs/python.md, "Install with pip").

    python_package_test.py wheel|pip --source DIR --work DIR --build-dir DIR --version V
                           [--data DIR]

wheel: `python3 -m build --no-isolation --wheel` makes the wheel. Its name carries the version and
       this interpreter's tags, and it holds the module, the stubs and no build path. It installs
       with `pip install --no-index` into a fresh `python3 -m venv --system-site-packages`.
pip:   `pip install --no-build-isolation --no-index SOURCE` into a fresh venv of the same kind.
(Before that, pip without cmake, a compiler, make and, as root, the headers: one message naming
the Debian packages, nothing installed.) Then, in both: check_python_install.py imports the installed copy from an empty folder, checks
the version and aligns the real desk pair against the truth; `pip uninstall` removes every file
that was installed; the source folder has no new file.

Both keep their CMake build in --build-dir ($LMALIGN_PIP_BUILD_DIR), so whichever runs second
reuses the first one's objects: ctest runs them one at a time (RESOURCE_LOCK). Run with the
interpreter under test (Debian's /usr/bin/python3). Exit code 77 (ctest: skipped) only when the
real data is missing outside CI.
"""
import argparse
import os
import pathlib
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import zipfile

from commands import check_call, run

HERE = pathlib.Path(__file__).resolve().parent
SKIP = 77


def fresh_venv(path, env):
    shutil.rmtree(path, ignore_errors=True)
    check_call([sys.executable, "-m", "venv", "--system-site-packages", path], env=env)
    python = path / "bin" / "python"
    site = subprocess.run([python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
                          check=True, capture_output=True, text=True).stdout.strip()
    return python, pathlib.Path(site)


def expected_wheel_name(version):
    """lmalign-V-cp3X-cp3X-linux_<arch>.whl: this interpreter's tags. The module links Debian's
    shared libraries, so the platform is the plain one (not manylinux)."""
    tag = "cp%d%d" % sys.version_info[:2]
    platform = sysconfig.get_platform().replace("-", "_").replace(".", "_")
    return "lmalign-%s-%s-%s-%s.whl" % (version, tag, tag, platform)


def check_wheel(wheel, version):
    ext_suffix = sysconfig.get_config_var("EXT_SUFFIX")
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        for name in ("lmalign/__init__.py", "lmalign/__init__.pyi", "lmalign/py.typed",
                     "lmalign/_lmalign" + ext_suffix):
            assert name in names, "%s not in the wheel: %s" % (name, sorted(names))
        init = z.read("lmalign/__init__.py").decode()
        assert '__version__ = "%s"' % version in init, "the wheel's __init__.py: no version"
        wheel_meta = z.read("lmalign-%s.dist-info/WHEEL" % version).decode()
        assert "Root-Is-Purelib: false" in wheel_meta, wheel_meta
        module = z.read("lmalign/_lmalign" + ext_suffix)
    # No RPATH into a build folder: the module loads only system libraries (checked on import).
    if shutil.which("readelf"):
        with tempfile.NamedTemporaryFile(suffix=ext_suffix) as f:
            f.write(module)
            f.flush()
            dynamic = subprocess.run(["readelf", "-d", f.name], check=True, capture_output=True,
                                     text=True).stdout
        assert "RPATH" not in dynamic and "RUNPATH" not in dynamic, dynamic
    print("wheel contents checked: %d files" % len(names))


def installed_files(python):
    """The files pip recorded for lmalign, absolute (from the RECORD of its .dist-info)."""
    out = subprocess.run(
        [python, "-c", "import importlib.metadata as m\n"
         "for f in m.files('lmalign'): print(f.locate())"],
        check=True, capture_output=True, text=True).stdout
    return [pathlib.Path(line) for line in out.splitlines() if line]


def check_and_uninstall(python, site, args, env, metadata=True):
    files = installed_files(python)
    assert any(f.name.startswith("_lmalign.") for f in files), files
    with tempfile.TemporaryDirectory() as empty:  # nothing importable from the current folder
        command = [python, HERE / "check_python_install.py", "--prefix", site,
                   "--version", args.version]
        if metadata:
            command.append("--metadata")
        if args.data:
            command += ["--data", args.data]
        checked = run(command, cwd=empty, env=env)
    if checked.returncode not in (0, SKIP):
        sys.exit("python package test: the installed package failed its check")
    check_call([python, "-m", "pip", "uninstall", "-y", "lmalign"], env=env)
    left = [f for f in files if f.exists()]
    assert not left, "left behind by pip uninstall: %s" % left
    left = sorted(p.name for p in site.iterdir() if p.name.lower().startswith("lmalign"))
    assert not left, "left behind in %s: %s" % (site, left)
    gone = subprocess.run([python, "-c", "import lmalign"], cwd=site.parent, env=env,
                          capture_output=True)
    assert gone.returncode != 0, "lmalign still importable after pip uninstall"
    print("pip uninstall removed all %d files" % len(files))
    return checked.returncode


# The headers the build needs (setup.py looks for them), and the Debian package of each.
HEADERS = [(sysconfig.get_paths()["include"], "python3-dev"),
           ("/usr/include/eigen3", "libeigen3-dev"), ("/usr/include/yaml-cpp", "libyaml-cpp-dev"),
           ("/usr/include/nlohmann", "nlohmann-json3-dev"),
           ("/usr/include/pybind11", "pybind11-dev")]


def check_missing_dependencies(python, site, args, env):
    """pip install . on a machine without the build dependencies stops before building, with one
    line naming the Debian packages, and leaves nothing installed. The machine is imitated by a
    PATH without cmake, a compiler and make and, as root where mount namespaces are allowed (CI),
    by empty folders mounted over the headers' folders for this command alone (unshare -m)."""
    command = [python, "-m", "pip", "install", "--no-build-isolation", "--no-index", args.source]
    missing = ["cmake", "g++", "make"]
    with tempfile.TemporaryDirectory() as empty:
        hide = [d for d, _ in HEADERS if os.path.isdir(d)]
        unshare, mount = shutil.which("unshare"), shutil.which("mount")  # (PATH is empty below)
        if os.geteuid() == 0 and unshare and mount and subprocess.run(
                [unshare, "-m", "true"], capture_output=True).returncode == 0:
            mounts = " && ".join("%s --bind %s %s" % (mount, empty, d) for d in hide)
            command = [unshare, "-m", "/bin/sh", "-c", mounts + ' && exec "$@"', "sh"] + command
            missing += [package for d, package in HEADERS if d in hide]
        else:
            print("(not root, or no mount namespace: only the missing programs are imitated)")
        done = run(command, env=dict(env, PATH=empty), capture_output=True, text=True)
    out = done.stdout + done.stderr
    print(out)
    expected = ("lmalign: cannot build the Python package: missing Debian packages: %s."
                % " ".join(missing))
    assert done.returncode != 0 and expected in out, "no message naming %s" % missing
    assert out.count("lmalign: cannot build") == 1, "the message is not given once"
    assert "lmalign: cmake" not in out, "CMake ran without its tools"
    left = sorted(p.name for p in site.iterdir() if p.name.lower().startswith("lmalign"))
    assert not left, "a failed pip install left %s in %s" % (left, site)
    print("missing build dependencies (%s): one message, nothing installed" % " ".join(missing))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("mode", choices=["wheel", "pip"])
    parser.add_argument("--source", required=True, type=pathlib.Path)
    parser.add_argument("--work", required=True, type=pathlib.Path)
    parser.add_argument("--build-dir", required=True)
    parser.add_argument("--version", required=True)
    parser.add_argument("--data")
    args = parser.parse_args()
    args.data = os.environ.get("LMALIGN_DATA") or args.data  # as the other tests

    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "PIP_"))}
    # pip as set up by Debian alone: no configuration file of this machine, no wheel cache.
    env.update(LMALIGN_PIP_BUILD_DIR=args.build_dir, PIP_DISABLE_PIP_VERSION_CHECK="1",
               PIP_CONFIG_FILE=os.devnull, PIP_NO_CACHE_DIR="1", PYTHONNOUSERSITE="1")
    env.setdefault("CMAKE_BUILD_PARALLEL_LEVEL", "2")
    work = args.work / args.mode
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    source_entries = sorted(p.name for p in args.source.iterdir())

    python, site = fresh_venv(work / "venv", env)
    if args.mode == "wheel":
        dist = work / "dist"
        check_call([sys.executable, "-m", "build", "--no-isolation", "--wheel", "--outdir", dist,
                    args.source], env=env)
        wheels = sorted(p.name for p in dist.iterdir())
        assert wheels == [expected_wheel_name(args.version)], wheels
        check_wheel(dist / wheels[0], args.version)
        check_call([python, "-m", "pip", "install", "--no-index", dist / wheels[0]], env=env)
    else:
        check_missing_dependencies(python, site, args, env)
        check_call([python, "-m", "pip", "install", "--no-build-isolation", "--no-index",
                    args.source], env=env)
    code = check_and_uninstall(python, site, args, env)

    # (__pycache__: a developer's own python3 -m py_compile while the test ran.)
    added = sorted(set(p.name for p in args.source.iterdir()) - set(source_entries)
                   - {"__pycache__"})
    assert not added, "written into the source folder: %s" % added
    if code == SKIP:
        if os.environ.get("CI") == "true":
            sys.exit("python package test: real data missing in CI")
        print("python package test: the desk pair was not checked (real data missing)")
    return code


if __name__ == "__main__":
    sys.exit(main())
