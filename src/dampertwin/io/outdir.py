"""Output folders: checked before any work (a folder or not yet there,
under a writable folder) and locked while a command writes them, so a second
run on the same OUT is refused instead of mixing its files with the first's.

The lock is a file named by a hash of OUT's real path in the temporary
folder's ``dampertwin-locks/`` holding the owner's process id and OUT; it is
removed when the command ends (SIGTERM included); one left by a killed process
(its id no longer running) is taken over.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import signal
import sys
import tempfile
import threading
from pathlib import Path

from ..errors import UserError


class OutputError(UserError):
    """An output folder or file that cannot be written (the message names the option and path)."""


def _existing_parent(p: Path) -> Path:
    q = p.parent
    while not q.exists() and q != q.parent:
        q = q.parent
    return q


def check_out_dir(out: str | os.PathLike, option: str = "--out", *, file: bool = False,
                  sibling: bool | None = None) -> Path:
    """``out`` may be written: a folder (or, ``file=True``, a file) or not yet
    there, below a writable folder. OutputError naming ``option`` otherwise.
    An existing writable folder needs no writable parent unless ``sibling``
    (a command that replaces OUT through a temporary folder beside it;
    default: a file, which is written beside itself and renamed)."""
    sibling = file if sibling is None else sibling
    o = Path(out)
    if str(out).strip() == "":
        raise OutputError(f"{option}: empty path; expected a {'file' if file else 'folder'}")
    if file:
        if o.is_dir():
            raise OutputError(f"{option} {out}: is a folder; expected a file path")
    elif o.exists() and not o.is_dir():
        raise OutputError(f"{option} {out}: exists and is not a folder")
    parent = _existing_parent(o.absolute())
    if not parent.is_dir():
        raise OutputError(f"{option} {out}: {parent} is a file, not a folder")
    if (sibling or not o.exists()) and not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {out}: folder {parent} is not writable")
    if o.exists() and not os.access(o, os.W_OK | (0 if file else os.X_OK)):
        raise OutputError(f"{option} {out}: not writable")
    return o


def check_targets(paths, option: str | None = None) -> list[Path]:
    """The files a command is about to write, checked before anything is written: none may be an existing
    folder, and the nearest existing folder above each must be a folder (not a file). OutputError naming the
    path (and ``option``) otherwise. Returns the paths."""
    out = [Path(p) for p in paths]
    where = f"{option}: " if option else ""
    for p in out:
        if p.is_dir():
            raise OutputError(f"{where}{p}: is a folder; expected a file path or nothing (remove or rename the folder)")
        parent = _existing_parent(p.absolute())
        if not parent.is_dir():
            raise OutputError(f"{where}{p}: {parent} is a file; expected a folder or nothing there")
    return out


@contextlib.contextmanager
def atomic_files(paths, suffix: str = "", option: str | None = None):
    """Temporary paths beside ``paths`` (``.NAME.tmpPID`` + ``suffix``) for the block to write; when it ends
    without error each is renamed onto its path (every file written before any is replaced), and whatever is
    left of them is removed in every case (an error, Ctrl-C, SIGTERM). :func:`check_targets` first: a target
    that is a folder is an OutputError before anything is written."""
    targets = check_targets(paths, option)
    tmps = [p.with_name(f".{p.name}.tmp{os.getpid()}{suffix}") for p in targets]
    try:
        yield tmps
        for tmp, p in zip(tmps, targets):
            os.replace(tmp, p)
    finally:
        for tmp in tmps:
            with contextlib.suppress(FileNotFoundError, IsADirectoryError):
                tmp.unlink()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def lock_path(out: str | os.PathLike) -> Path:
    """The lock file of output ``out``: one per real path, in the temporary folder's
    ``dampertwin-locks/`` (nothing is created beside OUT, not even its parent folder)."""
    real = os.path.realpath(os.fspath(out))
    name = hashlib.sha256(real.encode()).hexdigest()[:20]
    return Path(tempfile.gettempdir()) / "dampertwin-locks" / f"{name}.lock"


@contextlib.contextmanager
def out_lock(out: str | os.PathLike, option: str = "--out"):
    """Hold the lock of output ``out`` while the block runs (see the module
    docstring). A live owner: OutputError naming the lock and its process."""
    lock = lock_path(out)
    if not lock.parent.is_dir():
        lock.parent.mkdir(parents=True, exist_ok=True)
        with contextlib.suppress(OSError):
            lock.parent.chmod(0o1777)  # shared by every user, like /tmp
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            break
        except FileExistsError:
            try:
                pid = int((lock.read_text().split() or ["0"])[0])
            except (OSError, ValueError):
                pid = 0
            if pid and pid != os.getpid() and _alive(pid):
                raise OutputError(f"{option} {out}: another dampertwin run (process {pid}) is writing it; wait for "
                                  f"it to finish (lock file {lock})") from None
            lock.unlink(missing_ok=True)  # left by a killed run
        except OSError as e:
            raise OutputError(f"{option} {out}: cannot create the lock file {lock}: {e.strerror}") from None
    else:
        raise OutputError(f"{option} {out}: another run took the lock file {lock} meanwhile")
    with os.fdopen(fd, "w") as f:
        f.write(f"{os.getpid()} {os.path.realpath(os.fspath(out))}\n")
    old = None
    if threading.current_thread() is threading.main_thread():  # SIGTERM unwinds (lock and temp files removed)
        old = signal.getsignal(signal.SIGTERM)
        if old in (signal.SIG_DFL, None):
            signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))
        else:
            old = None
    try:
        yield lock
    finally:
        try:
            if (lock.read_text().split() or [""])[0] == str(os.getpid()):
                lock.unlink()
        except OSError:
            pass
        if old is not None:
            signal.signal(signal.SIGTERM, old)


__all__ = ["OutputError", "check_out_dir", "check_targets", "atomic_files", "out_lock", "lock_path"]
