"""``python -m wsnlib.studies.loss_tolerance``, for the tests of its command line.

:func:`run_as_module` runs the entry point in an interpreter of its own (once per test file is
enough); :func:`run_here` calls its ``main`` in the test's process, which saves the 2 s an
interpreter takes to import the study, for every other run and every refusal.
"""

import subprocess
import sys


def run_as_module(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "wsnlib.studies.loss_tolerance", *map(str, args)],
                          capture_output=True, text=True, timeout=900)


def run_here(capsys, *args) -> tuple[int, str, str]:
    """``(exit status, stdout, stderr)`` of ``main(args)``; a ``SystemExit`` message counts as stderr
    (as the interpreter would print it)."""
    from wsnlib.studies.loss_tolerance.__main__ import main

    capsys.readouterr()
    try:
        status, message = main([str(a) for a in args]), ""
    except SystemExit as exit:  # argparse's refusals (status 2) and the command's own (a message)
        status, message = (exit.code, "") if isinstance(exit.code, int) else (1, str(exit.code))
    out, err = capsys.readouterr()
    return status, out, err + message
