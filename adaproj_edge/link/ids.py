"""Numbers both ends agree on: the adaproj SMP group, its commands, the buffer size."""

from __future__ import annotations

from enum import IntEnum

ADAPROJ_GROUP = 65
"""The adaproj management group (user groups start at 64; 64 is Intercreate's)."""


class AdaprojCommand(IntEnum):
    """Commands of the adaproj group (read = op 0, write = op 2)."""

    LIST = 0
    """read: items, pending uploads, the active record, bytes used and the quota."""
    ACTIVATE = 1
    """write: show ``image`` (with optional ``mask`` and ``settings``)."""
    DELETE = 2
    """write: remove item ``name``."""
    STATUS = 3
    """read: the device's status, the store's figures, the link's counters."""
    SCREENSHOT = 4
    """read: the frame shown now, as PNG, in chunks from ``off``."""
    UPLOAD_STATE = 5
    """read: bytes received so far of the upload of ``name`` and their SHA-256."""


BUF_SIZE = 32768
"""The SMP buffer the server advertises: the largest message plus 4 (length, CRC)."""

DEFAULT_BUF_SIZE = 256
"""What a client assumes without MCUmgr params (smpmgr's 2 lines of 128)."""
