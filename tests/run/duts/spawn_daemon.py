"""A DUT that leaves a daemon behind, as a careless one does (issue 32).

:func:`start_daemon` starts ``sleep 600`` the classic way -- fork, ``setsid`` (a session
and process group of its own, out of the DUT's), fork again, the middle process exits --
so the daemon is an orphan in no group the bench started; it keeps the DUT's environment
and its standard output and error (a daemon that holds the DUT's pipes open). Its process
id is appended to a file.

As a command it wraps another one, for external and batch DUTs alike::

    python spawn_daemon.py PID_FILE -- COMMAND [ARGS...]

starts the daemon, then replaces itself (``exec``) with COMMAND, which thus keeps this
process's id.
"""

from __future__ import annotations

import os
import sys


def start_daemon(pid_file: str, argv: tuple[str, ...] = ("sleep", "600")) -> int:
    """Start ``argv`` as a daemon (double fork and ``setsid``); append its pid to
    ``pid_file`` and return it once the daemon runs ``argv`` (it has called ``exec``)."""
    r, w = os.pipe()  # close-on-exec: its end is closed when the daemon has exec'd
    middle = os.fork()
    if middle == 0:  # the middle process: a new session, the daemon, then gone
        try:
            os.close(r)
            os.setsid()
            daemon = os.fork()
            if daemon == 0:
                os.execvp(argv[0], list(argv))
            os.write(w, str(daemon).encode())
        finally:
            os._exit(0)
    os.close(w)
    with os.fdopen(r, "rb") as fh:
        daemon = int(fh.read())  # to the end: the middle has exited and the daemon exec'd
    os.waitpid(middle, 0)
    with open(pid_file, "a") as fh:
        fh.write(f"{daemon}\n")
    return daemon


if __name__ == "__main__":
    pid_file, sep, *command = sys.argv[1:]
    assert sep == "--" and command, __doc__
    start_daemon(pid_file)
    os.execvp(command[0], command)
