"""The type of a JSON object, shared by the modules that read or write one."""

from __future__ import annotations

from typing import Any, TypeAlias

#: A JSON object as parsed or about to be written. ``json.load`` types what it reads as
#: ``Any`` and each reader checks a value where it uses it (agents.artifacts.files.read_json,
#: the card and certificate checks), so the values stay unchecked here; a mapping that is
#: only passed on or written out is typed ``dict[str, object]`` instead.
JSONObject: TypeAlias = dict[str, Any]
