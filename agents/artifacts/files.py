"""Writing files atomically, and only where the caller said.

Every record the agents write goes through :func:`write_text`: the text goes to a
temporary file in the target's folder, which then replaces the target in one rename,
so a reader never sees half a file and an interrupted write leaves the old one.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def write_text(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (temporary name in the same folder, then rename).

    Raises:
        ValueError: If ``path`` is a symbolic link (nothing is written through one).
    """
    path = Path(path)
    if path.is_symlink():
        raise ValueError(f"{path} is a symbolic link; refusing to write through it")
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "w") as stream:
            stream.write(text)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path
