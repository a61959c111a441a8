"""Which code made a result: ``code_hash()`` is a content hash of the
package's source (``src/dampertwin/**/*.py``, paths and bytes, sorted), so a
committed ``metrics.json`` names the code it came from independently of git.
Same source, same hash; any edit of a source file changes it."""

from __future__ import annotations

import hashlib
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
PREFIX = "sha256:"
DIGITS = 16  # hex digits kept


def code_hash(package: str | Path = PACKAGE) -> str:
    """``sha256:<16 hex>`` over every ``*.py`` below ``package`` (relative path + content)."""
    package = Path(package)
    h = hashlib.sha256()
    for p in sorted(package.rglob("*.py")):
        if "__pycache__" in p.parts:
            continue
        h.update(p.relative_to(package).as_posix().encode() + b"\0")
        h.update(hashlib.sha256(p.read_bytes()).digest())
    return PREFIX + h.hexdigest()[:DIGITS]


def with_code_hash(metrics: dict) -> dict:
    """``metrics`` with ``code_hash`` of the running source added (first key)."""
    return {"code_hash": code_hash(), **{k: v for k, v in metrics.items() if k != "code_hash"}}


__all__ = ["code_hash", "with_code_hash"]
