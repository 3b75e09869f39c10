"""One line on standard error before this project's first kernel compiles in a process.

numba compiles a kernel the first time it runs and caches it on disk; until the cache
is filled, a first ``gym.make`` + ``step`` waits about a minute in silence. A listener on
numba's ``numba:compile`` event, which numba broadcasts only when it compiles (a kernel
loaded from the disk cache raises none), prints :data:`NOTICE` once per process, and
only for functions of ``dynamics``, ``trailer_env`` and ``agents``.
"""

from __future__ import annotations

import sys
from typing import Any

from numba.core import event

#: The line printed before the first compile.
NOTICE = (
    "trailer-env: compiling kernels once, about a minute; `trailer-env --compile` does it ahead"
)

#: The top-level packages whose kernels the notice speaks for.
PACKAGES = frozenset({"dynamics", "trailer_env", "agents"})


class CompileNotice(event.Listener):
    """Prints :data:`NOTICE` to standard error at the first compile of a project kernel."""

    def __init__(self) -> None:
        self.printed = False

    def on_start(self, event_: event.Event) -> None:
        """Print the notice when the compiling function is this project's, once."""
        if self.printed:
            return
        dispatcher: Any = (event_.data or {}).get("dispatcher")
        module = getattr(getattr(dispatcher, "py_func", None), "__module__", None) or ""
        if module.split(".")[0] in PACKAGES:
            self.printed = True
            print(NOTICE, file=sys.stderr, flush=True)

    def on_end(self, event_: event.Event) -> None:
        """Nothing to do when the compile ends."""


#: The process's one listener, registered when :mod:`dynamics` is first imported.
LISTENER = CompileNotice()
event.register("numba:compile", LISTENER)
