"""Typed JSON documents: frozen dataclasses read and written field by field.

Every document the agents write and read back (a model card, a certificate and its
starts, a results document) is a subclass of :class:`JSONRecord`: a frozen dataclass
whose field annotations say what JSON may hold there. :meth:`JSONRecord.from_json`
checks a parsed document whole against them before anything reads it, and refuses it
with a :class:`ValueError` naming the field; :meth:`JSONRecord.to_json` writes it back.

The annotations a field may have:

=================================  ==============================================
annotation                         JSON
=================================  ==============================================
``bool`` / ``int`` / ``str``       that type (a boolean is not an integer)
``float``                          a number (an integer is read as a float)
``X | None``                       ``X`` or null
``A | B``                          the first of ``A``, ``B`` that fits
``tuple[X, ...]``                  a list of ``X`` (read as a tuple)
``tuple[X, Y]``                    a list of exactly two, ``X`` then ``Y``
``Mapping[str, X]``                an object whose values are ``X`` (read as a dict)
``Literal["a", "b"]``              one of those values
a :class:`JSONRecord` subclass     an object read by that record
an :class:`enum.Enum` subclass     one of its values
``object``                         any JSON value, kept as parsed
=================================  ==============================================

A field with a default may be absent. A key the record does not declare is refused
(a misspelt field must not read as its default). Each record has a
:attr:`~JSONRecord.SCHEMA_VERSION` written as ``schema_version``; a document without
one is version 1 (documents written before versions existed), and a document of a
newer version than this code reads is refused, naming both versions.

A :class:`SparseRecord` (nested: :class:`SparsePart`) writes only the fields that differ
from their defaults (and those it names in ``ALWAYS``), so that a document with optional
fields reads and writes back as it was.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import types
import typing
from collections.abc import Mapping
from typing import ClassVar, Literal, TypeGuard, TypeVar, Union, get_args, get_origin

#: The key that holds a document's schema version.
SCHEMA_KEY = "schema_version"

RecordT = TypeVar("RecordT", bound="JSONRecord")


class DocumentError(ValueError):
    """A JSON document does not fit its record (the message names the field)."""


@dataclasses.dataclass(frozen=True)
class JSONRecord:
    """Base of the typed documents (see the module docstring for the annotations).

    Subclasses are ``@dataclasses.dataclass(frozen=True)``; they may check values
    beyond their types in ``__post_init__`` by raising :class:`DocumentError`.
    """

    #: The newest version of the document this code writes and reads.
    SCHEMA_VERSION: ClassVar[int] = 1
    #: What the document is, in words, for error messages ("model card").
    DOCUMENT: ClassVar[str] = "document"
    #: Whether ``to_json`` writes ``schema_version`` (nested parts do not).
    VERSIONED: ClassVar[bool] = True

    @classmethod
    def from_json(cls: type[RecordT], data: object, where: str = "") -> RecordT:
        """The record that ``data`` (a parsed JSON document) holds.

        Raises:
            DocumentError: Naming ``where`` and the first field that is missing,
                unknown or of the wrong type, or a schema version newer than
                :attr:`SCHEMA_VERSION`.
        """
        label = f"{cls.DOCUMENT} {where}".strip()
        return cls._read(data, label, versioned=cls.VERSIONED)

    @classmethod
    def _read(cls: type[RecordT], data: object, label: str, *, versioned: bool) -> RecordT:
        if not isinstance(data, dict):
            raise DocumentError(f"{label}: must be a JSON object, got {_kind(data)}")
        data = dict(data)
        if versioned:
            version = data.pop(SCHEMA_KEY, 1)
            if not _is_int(version) or version < 1:
                raise DocumentError(f"{label}: {SCHEMA_KEY} must be a positive integer")
            if version > cls.SCHEMA_VERSION:
                raise DocumentError(
                    f"{label}: {SCHEMA_KEY} {version} is newer than this trailer-env "
                    f"reads ({cls.SCHEMA_VERSION}); upgrade trailer-env"
                )
        hints = _hints(cls)
        values: dict[str, object] = {}
        for field in dataclasses.fields(cls):
            if not field.init or not _in_json(field):
                continue
            if field.name not in data:
                if (
                    field.default is dataclasses.MISSING
                    and field.default_factory is dataclasses.MISSING
                ):
                    raise DocumentError(f"{label}: missing field {field.name!r}")
                continue
            raw = data.pop(field.name)
            values[field.name] = _convert(raw, hints[field.name], label, field.name)
        if data:
            unknown = ", ".join(repr(key) for key in sorted(data))
            raise DocumentError(f"{label}: unknown field {unknown}")
        try:
            return cls(**values)
        except DocumentError as error:
            raise DocumentError(f"{label}: {error}") from None

    def to_json(self) -> dict[str, object]:
        """The document as JSON-ready data (fields at their defaults included)."""
        document: dict[str, object] = {}
        if self.VERSIONED:
            document[SCHEMA_KEY] = self.SCHEMA_VERSION
        for field in dataclasses.fields(self):
            if _in_json(field):
                document[field.name] = _dump(getattr(self, field.name))
        return document

    def replace(self: RecordT, **changes: object) -> RecordT:
        """A copy with ``changes`` (field name -> value), checked like a new record."""
        return dataclasses.replace(self, **changes)


@dataclasses.dataclass(frozen=True)
class JSONPart(JSONRecord):
    """A record nested in a document: read and written without a schema version."""

    VERSIONED: ClassVar[bool] = False
    DOCUMENT: ClassVar[str] = "part"


@dataclasses.dataclass(frozen=True)
class SparseRecord(JSONRecord):
    """A record whose ``to_json`` leaves out the fields at their defaults (an absent
    field reads as its default, so nothing is lost), but those named in :attr:`ALWAYS`."""

    #: Fields written even at their default.
    ALWAYS: ClassVar[tuple[str, ...]] = ()

    def to_json(self) -> dict[str, object]:
        """The document as JSON-ready data, without the fields at their defaults."""
        document = super().to_json()
        for field in dataclasses.fields(self):
            if field.name in self.ALWAYS:
                continue
            if field.default is not dataclasses.MISSING:
                default = field.default
            elif field.default_factory is not dataclasses.MISSING:
                default = field.default_factory()
            else:
                continue
            if getattr(self, field.name) == default:
                document.pop(field.name, None)
        return document


@dataclasses.dataclass(frozen=True)
class SparsePart(SparseRecord):
    """A :class:`SparseRecord` nested in a document (no schema version of its own)."""

    VERSIONED: ClassVar[bool] = False
    DOCUMENT: ClassVar[str] = "part"


def _hints(cls: type) -> dict[str, object]:
    return typing.get_type_hints(cls)


#: A field's metadata that keeps it out of the generic reading and writing: a record
#: whose subclass reads and writes that field itself (``field(metadata=NOT_IN_JSON)``).
_IN_JSON = "in_json"
NOT_IN_JSON: Mapping[str, object] = {_IN_JSON: False}


def _in_json(field: dataclasses.Field[object]) -> bool:
    return field.metadata.get(_IN_JSON, True) is not False


def _is_record(annotation: object) -> TypeGuard[type[JSONRecord]]:
    return isinstance(annotation, type) and issubclass(annotation, JSONRecord)


def _kind(value: object) -> str:
    if value is None:
        return "null"
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, list):
        return "a list"
    return f"{type(value).__name__} {value!r:.60}"


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _describe(annotation: object) -> str:
    origin = get_origin(annotation)
    if annotation is type(None):
        return "null"
    if origin in (Union, types.UnionType):
        return " or ".join(_describe(arg) for arg in get_args(annotation))
    if origin is Literal:
        return "one of " + ", ".join(repr(arg) for arg in get_args(annotation))
    if origin is tuple:
        args = get_args(annotation)
        return "a list" if args[-1] is Ellipsis else f"a list of {len(args)}"
    if origin in (Mapping, dict):
        return "an object"
    if isinstance(annotation, type) and issubclass(annotation, JSONRecord):
        return "an object"
    if isinstance(annotation, type) and issubclass(annotation, enum.Enum):
        return "one of " + ", ".join(repr(member.value) for member in annotation)
    return getattr(annotation, "__name__", str(annotation))


def _convert(value: object, annotation: object, label: str, name: str) -> object:
    """``value`` read as ``annotation`` (see the module docstring), or DocumentError."""
    origin = get_origin(annotation)
    wrong = DocumentError(f"{label}: {name!r} must be {_describe(annotation)}, got {_kind(value)}")
    if annotation is object:
        return value
    if annotation is type(None):
        if value is None:
            return None
        raise wrong
    if origin in (Union, types.UnionType):
        for alternative in get_args(annotation):
            try:
                return _convert(value, alternative, label, name)
            except DocumentError as error:
                # An object meant for a record part: its own message names the field.
                if _is_record(alternative) and isinstance(value, dict):
                    raise error from None
        raise wrong
    if origin is Literal:
        if value in get_args(annotation) and not isinstance(value, bool):
            return value
        raise wrong
    if origin is tuple:
        if not isinstance(value, list):
            raise wrong
        args = get_args(annotation)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(
                _convert(item, args[0], label, f"{name}[{index}]")
                for index, item in enumerate(value)
            )
        if len(value) != len(args):
            raise DocumentError(
                f"{label}: {name!r} must be a list of {len(args)}, got {len(value)} items"
            )
        return tuple(
            _convert(item, arg, label, f"{name}[{index}]")
            for index, (item, arg) in enumerate(zip(value, args, strict=True))
        )
    if origin in (Mapping, dict):
        if not isinstance(value, dict):
            raise wrong
        _, value_type = get_args(annotation)
        return {
            str(key): _convert(item, value_type, label, f"{name}.{key}")
            for key, item in value.items()
        }
    if _is_record(annotation):
        if not isinstance(value, dict):
            raise wrong
        return annotation._read(value, f"{label}: {name}", versioned=False)
    if isinstance(annotation, type) and issubclass(annotation, enum.Enum):
        try:
            return annotation(value)
        except ValueError:
            raise wrong from None
    if annotation is bool:
        if isinstance(value, bool):
            return value
        raise wrong
    if annotation is int:
        if _is_int(value):
            return value
        raise wrong
    if annotation is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        raise wrong
    if annotation is str:
        if isinstance(value, str):
            return value
        raise wrong
    raise TypeError(f"{label}: field {name!r} has an annotation records cannot read: {annotation}")


def _dump(value: object) -> object:
    if isinstance(value, JSONRecord):
        part = value.to_json()
        part.pop(SCHEMA_KEY, None)
        return part
    if isinstance(value, enum.Enum):
        return value.value
    if isinstance(value, tuple | list):
        return [_dump(item) for item in value]
    if isinstance(value, Mapping):
        return {key: _dump(item) for key, item in value.items()}
    return value


def finite(value: float) -> bool:
    """Whether a float field's value is finite (for ``__post_init__`` checks)."""
    return math.isfinite(value)


__all__ = [
    "NOT_IN_JSON",
    "SCHEMA_KEY",
    "DocumentError",
    "JSONPart",
    "JSONRecord",
    "SparsePart",
    "SparseRecord",
    "finite",
]
