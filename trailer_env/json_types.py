"""The type of a JSON object, shared by the modules that read or write one."""

from __future__ import annotations

from typing import Any, TypeAlias

#: A JSON object as parsed or about to be written. ``json.load`` leaves its values
#: untyped and each reader checks a value where it uses it (the card, certificate and
#: statistics checks), so the alias does not claim more; a mapping that is only built,
#: passed on or written out is typed ``dict[str, object]`` instead.
JSONObject: TypeAlias = dict[str, Any]
