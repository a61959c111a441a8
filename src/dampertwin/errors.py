"""User errors (bad input named by file, key or column) versus bugs.

Every error the project raises for bad input derives from :class:`UserError`;
:func:`run_main` turns one into a single clean line on stderr and exit code 2.
Tracebacks are shown only for real bugs, or for user errors with ``--debug``
or the environment variable ``DAMPERTWIN_DEBUG=1``.
"""

from __future__ import annotations

import os
import sys
import traceback
from typing import Callable

USER_ERROR_EXIT = 2


class UserError(ValueError):
    """Bad input: the message names the file and key / column and what was expected."""

    def __init__(self, errors: list[str] | str):
        self.errors = [errors] if isinstance(errors, str) else list(errors)
        super().__init__("\n".join(self.errors))


def one_line(e: BaseException) -> str:
    """A user error as one line (several problems joined by '; ')."""
    errs = getattr(e, "errors", None)
    if not errs:
        errs = [str(e) or type(e).__name__]
    return "; ".join(" ".join(str(x).split()) for x in errs)


def debug_enabled(argv: list[str] | None = None) -> bool:
    return os.environ.get("DAMPERTWIN_DEBUG", "").strip() not in ("", "0", "false", "no") or \
        bool(argv and "--debug" in argv)


def user_error_types() -> tuple[type, ...]:
    """Exception types that mean bad input (config overrides included)."""
    types: list[type] = [UserError, FileNotFoundError]
    try:
        from hydra.errors import HydraException
        from omegaconf.errors import OmegaConfBaseException

        types += [HydraException, OmegaConfBaseException]
    except ImportError:  # pragma: no cover
        pass
    return tuple(types)


def run_main(main: Callable[..., object], argv: list[str] | None = None, prog: str | None = None) -> int:
    """Call ``main(*argv)`` (``--debug`` removed); a user error (UserError,
    missing file) is one line ``prog: message`` and exit 2; other exceptions
    propagate (a bug keeps its traceback)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = debug_enabled(argv)
    args = [a for a in argv if a != "--debug"]
    prog = prog or os.path.basename(sys.argv[0] or "dampertwin")
    try:
        main(*args)
    except user_error_types() as e:
        if debug:
            traceback.print_exc()
        print(f"{prog}: error: {one_line(e)}", file=sys.stderr)
        return USER_ERROR_EXIT
    return 0


__all__ = ["UserError", "USER_ERROR_EXIT", "one_line", "debug_enabled", "run_main", "user_error_types"]
