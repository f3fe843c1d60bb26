"""RTDE wire format (TCP port 30004): message framing, value types and recipe codecs.

Every message is ``uint16 size`` (header included) + ``uint8 type`` + payload, big-endian. This
module only packs and unpacks bytes: the simulated controller's answers live in
:mod:`urident.simcontroller.server`, the session recorder's requests in :mod:`urident.session.recorder`.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Callable, Sequence

HEADER = struct.Struct(">HB")
HEADER_SIZE = HEADER.size

# Message types (ASCII letters).
REQUEST_PROTOCOL_VERSION = ord("V")
GET_URCONTROL_VERSION = ord("v")
TEXT_MESSAGE = ord("M")
DATA_PACKAGE = ord("U")
CONTROL_PACKAGE_SETUP_OUTPUTS = ord("O")
CONTROL_PACKAGE_SETUP_INPUTS = ord("I")
CONTROL_PACKAGE_START = ord("S")
CONTROL_PACKAGE_PAUSE = ord("P")

# RTDE value type name -> (struct code, number of elements).
VALUE_TYPES: dict[str, tuple[str, int]] = {
    "BOOL": ("?", 1),
    "UINT8": ("B", 1),
    "UINT32": ("I", 1),
    "UINT64": ("Q", 1),
    "INT32": ("i", 1),
    "DOUBLE": ("d", 1),
    "VECTOR3D": ("ddd", 3),
    "VECTOR6D": ("dddddd", 6),
    "VECTOR6INT32": ("iiiiii", 6),
    "VECTOR6UINT32": ("IIIIII", 6),
}

NOT_FOUND = "NOT_FOUND"
IN_USE = "IN_USE"


class ProtocolError(Exception):
    """The peer sent bytes that are not a valid RTDE message."""


def frame(message_type: int, payload: bytes = b"") -> bytes:
    """One complete message: header + payload."""
    size = HEADER_SIZE + len(payload)
    if size > 0xFFFF:
        raise ProtocolError(f"RTDE message of {size} bytes exceeds 65535")
    return HEADER.pack(size, message_type) + payload


class MessageReader:
    """Splits a byte stream into ``(type, payload)`` messages; feed it whatever ``recv`` returned."""

    def __init__(self) -> None:
        self._buffer = bytearray()

    def feed(self, data: bytes) -> list[tuple[int, bytes]]:
        self._buffer += data
        messages = []
        while len(self._buffer) >= HEADER_SIZE:
            size, message_type = HEADER.unpack_from(self._buffer)
            if size < HEADER_SIZE:
                raise ProtocolError(f"RTDE header declares size {size} < {HEADER_SIZE}")
            if len(self._buffer) < size:
                break
            messages.append((message_type, bytes(self._buffer[HEADER_SIZE:size])))
            del self._buffer[:size]
        return messages


def parse_names(payload: bytes) -> list[str]:
    """Comma-separated variable names; ur_rtde leaves a trailing comma, so empty items are dropped."""
    text = payload.decode("ascii", errors="replace")
    return [name.strip() for name in text.split(",") if name.strip()]


def parse_output_setup(payload: bytes, protocol_version: int) -> tuple[float | None, list[str]]:
    """``O`` request: (requested frequency [Hz] or None for protocol 1, names)."""
    if protocol_version >= 2:
        if len(payload) < 8:
            raise ProtocolError("setup-outputs request shorter than its frequency field")
        (frequency,) = struct.unpack_from(">d", payload)
        return frequency, parse_names(payload[8:])
    return None, parse_names(payload)


def setup_reply(message_type: int, recipe_id: int, types: Sequence[str]) -> bytes:
    """``O``/``I`` reply: uint8 recipe id + comma-separated type names."""
    return frame(message_type, struct.pack(">B", recipe_id) + ",".join(types).encode("ascii"))


def version_reply(major: int, minor: int, bugfix: int, build: int) -> bytes:
    return frame(GET_URCONTROL_VERSION, struct.pack(">IIII", major, minor, bugfix, build))


def success_reply(message_type: int, success: bool) -> bytes:
    return frame(message_type, struct.pack(">B", 1 if success else 0))


def text_message(message: str, source: str = "urident-sim", level: int = 1) -> bytes:
    """``M`` (protocol 2): uint8 length + message, uint8 length + source, uint8 warning level."""
    m = message.encode("utf-8")[:255]
    s = source.encode("utf-8")[:255]
    return frame(TEXT_MESSAGE, bytes([len(m)]) + m + bytes([len(s)]) + s + bytes([level]))


@dataclass
class Recipe:
    """A configured recipe: names, RTDE types and the struct that packs or unpacks one package.

    ``getters`` (output recipes only) hold one callable per name; each returns a number or a
    sequence of numbers for the vector types.
    """

    recipe_id: int
    names: list[str]
    types: list[str]
    codec: struct.Struct
    vector: list[bool]
    getters: list[Callable] | None = None
    ticks_per_package: int = 1

    @classmethod
    def build(cls, recipe_id: int, names: list[str], types: list[str],
              getters: list[Callable] | None = None, ticks_per_package: int = 1) -> "Recipe":
        fmt = ">B" + "".join(VALUE_TYPES[t][0] for t in types)
        vector = [VALUE_TYPES[t][1] > 1 for t in types]
        return cls(recipe_id, names, types, struct.Struct(fmt), vector, getters, ticks_per_package)

    def pack(self, values: Sequence) -> bytes:
        """A ``U`` data package from one value per name (vectors as sequences)."""
        flat: list = [self.recipe_id]
        for value, is_vector in zip(values, self.vector):
            if is_vector:
                flat.extend(value)
            else:
                flat.append(value)
        return frame(DATA_PACKAGE, self.codec.pack(*flat))

    def unpack(self, payload: bytes) -> dict[str, object]:
        """Values of a ``U`` package sent by a client, by name (payload includes the recipe id).

        ur_rtde sometimes sends fewer bytes than the recipe declares (e.g. a command id alone in
        a wider recipe); the names it did not fill are left out.
        """
        if len(payload) >= self.codec.size:
            flat = self.codec.unpack_from(payload)
            return self._regroup(flat[1:])
        values: dict[str, object] = {}
        offset = 1
        for name, rtde_type in zip(self.names, self.types):
            code, count = VALUE_TYPES[rtde_type]
            item = struct.Struct(">" + code)
            if offset + item.size > len(payload):
                break
            unpacked = item.unpack_from(payload, offset)
            values[name] = list(unpacked) if count > 1 else unpacked[0]
            offset += item.size
        return values

    def _regroup(self, flat: Sequence) -> dict[str, object]:
        values: dict[str, object] = {}
        k = 0
        for name, rtde_type in zip(self.names, self.types):
            count = VALUE_TYPES[rtde_type][1]
            if count > 1:
                values[name] = list(flat[k:k + count])
            else:
                values[name] = flat[k]
            k += count
        return values
