"""SMP messages on the server side: the 8-byte header, the CBOR body, replies, errors.

The header is ``op:3 bits | version:2 bits`` (one byte), ``flags`` (one byte),
``length`` (uint16, CBOR body bytes), ``group`` (uint16), ``sequence`` (one byte),
``command`` (one byte), all big-endian. A reply copies group, sequence, command and
version, and sets the op to READ_RSP or WRITE_RSP.

Errors take two shapes, as in Zephyr: a management error ``{"rc": code, "rsn":
text}`` (any version; ``rsn`` is the reason, for people), and, for version-2
requests, a group error ``{"err": {"group": g, "rc": code}}`` for the codes a group
defines (file not found, offset not valid, ...). ``smpclient`` parses the first as
``ErrorV1`` and the second as the group's ``ErrorV2``.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum
from typing import Any, TypeVar

import cbor2
from smp.error import MGMT_ERR

HEADER = struct.Struct("!BBHHBB")


class Op(IntEnum):
    """SMP header operation: a read or write request, or its response."""

    READ = 0
    READ_RSP = 1
    WRITE = 2
    WRITE_RSP = 3


MAX_BODY = 0xFFFF - 2 - HEADER.size
"""Largest reply body: a serial frame holds 65535 bytes with its CRC."""

MAX_DEPTH = 4
"""Deepest nesting accepted in a request body (settings are a map in a map)."""


class SmpError(Exception):
    """A request the server answers with an error.

    Parameters
    ----------
    rc : int
        A ``MGMT_ERR`` code, or the group's own code when ``group`` is given.
    reason : str
        What went wrong, for the person at the other end (sent as ``rsn``).
    group : int or None
        Set for a group error (``{"err": {...}}``); ``None`` for a management error.
    extra : dict
        More fields for the reply (Zephyr adds ``len`` to an offset error).
    legacy : int
        The ``MGMT_ERR`` code a version-1 client gets for a group error.
    """

    def __init__(
        self,
        rc: int,
        reason: str,
        *,
        group: int | None = None,
        extra: dict[str, Any] | None = None,
        legacy: int = MGMT_ERR.EUNKNOWN,
    ) -> None:
        super().__init__(reason)
        self.rc = int(rc)
        self.reason = reason
        self.group = group
        self.extra = extra or {}
        self.legacy = int(legacy)


@dataclass(frozen=True)
class Request:
    """One decoded request: the header fields and the CBOR map of the body."""

    op: int
    version: int
    flags: int
    group: int
    sequence: int
    command: int
    body: dict[str, Any]

    def reply(self, body: dict[str, Any]) -> bytes:
        """The response message carrying ``body``; :class:`SmpError` if it cannot fit."""
        data = cbor2.dumps(body)
        if len(data) > MAX_BODY:
            raise SmpError(MGMT_ERR.EMSGSIZE, f"the reply would be {len(data)} bytes")
        op = Op.READ_RSP if self.op == Op.READ else Op.WRITE_RSP
        return (
            HEADER.pack(
                (self.version & 0b11) << 3 | op,
                0,
                len(data),
                self.group,
                self.sequence,
                self.command,
            )
            + data
        )

    def error(self, e: SmpError) -> bytes:
        """The error response for ``e``, shaped for this request's version."""
        if e.group is not None and self.version >= 1:
            return self.reply({"err": {"group": e.group, "rc": e.rc}, **e.extra})
        rc = e.rc if e.group is None else e.legacy
        return self.reply({"rc": rc, "rsn": e.reason})


def _refuse_tag(_decoder: object, _value: object) -> Any:
    raise ValueError("CBOR tags are not accepted")


def _refuse_unknown_tag(_tag: object, _immutable: bool) -> Any:
    raise ValueError("CBOR tags are not accepted")


# every tag cbor2 decodes itself (dates, bignums, regexes, sets, shared references, ...)
_NO_TAGS = {tag: _refuse_tag for tag in (*range(0, 300), 1004, 55799)}


def parse_header(message: bytes) -> tuple[int, int, int, int, int, int, int]:
    """(op, version, flags, length, group, sequence, command) of a message's header."""
    if len(message) < HEADER.size:
        raise ValueError(f"{len(message)} bytes is too short for an SMP header")
    b0, flags, length, group, seq, cmd = HEADER.unpack_from(message)
    return b0 & 0b111, (b0 >> 3) & 0b11, flags, length, group, seq, cmd


def decode_body(data: bytes) -> dict[str, Any]:
    """The request's CBOR map; raises :class:`SmpError` for anything else.

    Tags, duplicate keys, non-string keys and nesting deeper than :data:`MAX_DEPTH`
    are refused, so nothing in a request can cost more than its own size to decode.
    """
    if not data:
        return {}
    try:
        body = cbor2.loads(
            data,
            max_depth=MAX_DEPTH,
            allow_duplicate_keys=False,
            semantic_decoders=_NO_TAGS,
            tag_hook=_refuse_unknown_tag,
        )
    except Exception as e:  # cbor2 raises several types for bad input; all mean the same
        raise SmpError(MGMT_ERR.EINVAL, f"body is not valid CBOR: {e}") from None
    if not isinstance(body, dict) or not all(isinstance(k, str) for k in body):
        raise SmpError(MGMT_ERR.EINVAL, "body must be a CBOR map with text keys")
    return body


T = TypeVar("T")


def field(body: dict[str, Any], key: str, kind: type[T], default: T | None = None) -> T:
    """``body[key]`` checked to be a ``kind``; missing means ``default`` (if given).

    ``bool`` is not accepted where an ``int`` is asked for.
    """
    if key not in body:
        if default is None:
            raise SmpError(MGMT_ERR.EINVAL, f"field {key!r} is missing")
        return default
    value = body[key]
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise SmpError(
            MGMT_ERR.EINVAL, f"field {key!r} must be {kind.__name__}, not {type(value).__name__}"
        )
    if kind is int and not 0 <= value < 2**63:  # type: ignore[operator]
        raise SmpError(MGMT_ERR.EINVAL, f"field {key!r} is out of range")
    return value


def optional(body: dict[str, Any], key: str, kind: type[T]) -> T | None:
    """``body[key]`` checked like :func:`field`, or ``None`` when it is absent."""
    if key not in body or body[key] is None:
        return None
    return field(body, key, kind)
