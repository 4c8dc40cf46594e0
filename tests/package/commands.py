"""Running commands for the install tests (python_package_test.py, deb_package_test.py): each
command is printed with its time and exit code, so that ctest's output shows what took how long."""
import subprocess
import sys
import time


def run(command, **kwargs):
    """subprocess.run, printed; returns the CompletedProcess whatever the exit code."""
    print("$", " ".join(map(str, command)), flush=True)
    start = time.monotonic()
    done = subprocess.run([str(c) for c in command], **kwargs)
    print("  (%.1f s, exit %d)" % (time.monotonic() - start, done.returncode), flush=True)
    return done


def check_call(command, **kwargs):
    """run(), and the test stops (exit 1, naming the command) unless the command succeeded."""
    done = run(command, **kwargs)
    if done.returncode != 0:
        sys.exit("install test: failed (exit %d): %s"
                 % (done.returncode, " ".join(map(str, command))))
    return done
