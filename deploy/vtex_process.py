"""A `vtex serve` process for the deploy/ checks: started with the given arguments and
environment, its URL read from the line it prints once listening, stopped on leaving."""

import contextlib
import re
import subprocess
import sys


@contextlib.contextmanager
def serving(vtex_bin, args, env=None):
    """Runs `vtex_bin args` and yields its base URL; exits naming the line it printed instead
    when it does not start."""
    proc = subprocess.Popen([vtex_bin, *args], env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        line = proc.stdout.readline()
        m = re.match(r"vtex listening on (http://\S+)", line)
        if not m:
            sys.exit(f"vtex {' '.join(args)} did not start: {line!r}")
        yield m.group(1)
    finally:
        proc.terminate()
        proc.wait(timeout=15)
