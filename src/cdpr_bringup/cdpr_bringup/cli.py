"""What every cdpr-* command does with a user's mistake: one line, exit 2, no traceback
(unless --debug)."""
from __future__ import annotations

import functools
import sys

from cdpr_control.config import ConfigError

# The exit code of a command-line mistake, as argparse uses it.
USAGE_EXIT_CODE = 2
# What a shell reports for a command ended by Ctrl-C (128 + SIGINT).
INTERRUPTED_EXIT_CODE = 130
DEBUG_FLAG = '--debug'


class UsageError(ValueError):
    """A command-line option has a value the run cannot use; the message names it."""


USER_ERRORS = (ConfigError, UsageError, FileNotFoundError)


def command(name: str):
    """Decorate `main(argv)` of the command `name`: a user error (a bad config names its
    key and file, a bad option its flag) is printed as one line and the command exits 2;
    with --debug anywhere on the command line, the traceback comes too."""
    def decorate(main):
        @functools.wraps(main)
        def run(argv=None):
            argv = list(sys.argv[1:] if argv is None else argv)
            debug = DEBUG_FLAG in argv
            try:
                return main([arg for arg in argv if arg != DEBUG_FLAG])
            except USER_ERRORS as err:
                if debug:
                    raise
                print(f'{name}: {err}', file=sys.stderr)
                return USAGE_EXIT_CODE
        return run
    return decorate
