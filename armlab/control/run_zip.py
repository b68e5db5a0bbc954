"""A run file's zip read in memory, trusting nothing it declares (docs/runs.md).

Python's :mod:`zipfile` is not used to read: it unpacks bzip2 and LZMA members in one
step whatever their header declares, counts members from the end record's claim, and
cuts a member's name at a NUL. Here:

- the end record (and its ZIP64 record) only says where the central directory is: a
  claim of more than :data:`MAX_MEMBERS` members or a directory over
  :data:`MAX_DIRECTORY_BYTES` is refused at once, and otherwise the members are counted
  as the directory is walked (the walk stops at the first member over the limit);
- every member must be stored or deflated (no bzip2, LZMA, ...), unencrypted, named by a
  relative path of at most :data:`MAX_NAME_BYTES` bytes without NUL, control characters,
  backslashes, drives or "..", and named once;
- a member is unpacked in chunks (:func:`iter_member`), never past the smaller of its
  declared size and the caller's limit, and never past :data:`MAX_RATIO` times what it
  has consumed (past :data:`RATIO_FLOOR_BYTES`); its end, length and CRC are checked
  against the central directory (so ZIP64 sizes and data descriptors read alike).

Every refusal is one :class:`~armlab.control.run_errors.RunFileError`.
"""

from __future__ import annotations

import re
import struct
import zlib
from collections.abc import Generator, Iterator
from dataclasses import dataclass

from armlab.control.run_errors import RunFileError, quote

#: The most members a run file may hold (it needs two; the rest are ignored).
MAX_MEMBERS = 64
#: The largest central directory (bytes).
MAX_DIRECTORY_BYTES = 2**20
#: The longest member name (bytes, as stored).
MAX_NAME_BYTES = 255
#: A member unpacking to more than this many times its packed size (and to more than
#: :data:`RATIO_FLOOR_BYTES`) is taken for a zip bomb.
MAX_RATIO = 200
RATIO_FLOOR_BYTES = 2**20
#: The only compression methods read: stored and deflate.
STORED, DEFLATED = 0, 8
METHOD_NAMES = {1: "shrink", 6: "implode", 9: "deflate64", 12: "bzip2", 14: "LZMA",
                93: "zstandard", 95: "xz", 98: "PPMd", 99: "AES"}

_IN_CHUNK = 2**16
_OUT_CHUNK = 2**20
_END = b"PK\x05\x06"
_END64 = b"PK\x06\x06"
_LOCATOR64 = b"PK\x06\x07"
_CENTRAL = b"PK\x01\x02"
_LOCAL = b"PK\x03\x04"
_END_FMT = struct.Struct("<4sHHHHIIH")  # 22 bytes
_LOCATOR_FMT = struct.Struct("<4sIQI")  # 20 bytes
_END64_FMT = struct.Struct("<4sQHHIIQQQQ")  # 56 bytes
_CENTRAL_FMT = struct.Struct("<4sHHHHHHIIIHHHHHII")  # 46 bytes
_LOCAL_FMT = struct.Struct("<4sHHHHHIIIHH")  # 30 bytes
_DRIVE = re.compile(r"^[A-Za-z]:")


@dataclass(frozen=True)
class Member:
    """One member as the central directory lists it (sizes from ZIP64 fields if any).

    Attributes:
        name: its name (UTF-8 when flagged so, else code page 437, as zip tools write).
        method: compression method (:data:`STORED` or :data:`DEFLATED`).
        flags: the general purpose flags.
        crc: CRC-32 of its unpacked bytes.
        packed: compressed size, bytes.
        size: declared unpacked size, bytes.
        offset: where its local header starts in the file.
    """

    name: str
    method: int
    flags: int
    crc: int
    packed: int
    size: int
    offset: int


def damaged(label: str, why: str) -> RunFileError:
    """The refusal of a truncated or damaged zip."""
    return RunFileError(f"{label} is truncated or damaged ({why}): download or copy it again")


def list_members(data: bytes, label: str) -> dict[str, Member]:
    """The members of the zip ``data``, name -> :class:`Member`, every one checked (see the
    module docstring): counted from the directory read, not from the end record."""
    start, end, claimed, claimed_size = _directory_bounds(data, label)
    if claimed > MAX_MEMBERS or claimed_size > MAX_DIRECTORY_BYTES:
        raise _too_many(label, f"lists {claimed} members in a {claimed_size}-byte directory")
    shift = start - _directory_offset(data, end)
    out: dict[str, Member] = {}
    at = start
    while at < end:
        if len(out) == MAX_MEMBERS:
            raise _too_many(label, f"holds more than {MAX_MEMBERS} members")
        member, at = _central_entry(data, at, end, shift, label)
        if member.name in out:
            raise RunFileError(f"{label} holds two members named {quote(member.name)}; "
                               "refused: it was not written by armlab")
        out[member.name] = member
    if at != end:
        raise damaged(label, "its zip directory overruns its end record")
    return out


def _too_many(label: str, what: str) -> RunFileError:
    return RunFileError(f"{label} {what}; a run file holds two (at most {MAX_MEMBERS}): "
                        "refused, it was not written by armlab")


def _directory_offset(data: bytes, end: int) -> int:
    """The directory's offset as the end record at ``end`` states it (a prefix before the
    zip, as a self-extracting archive has, shifts every offset by the same amount)."""
    if data[end:end + 4] == _END64:
        return _END64_FMT.unpack_from(data, end)[9]
    return _END_FMT.unpack_from(data, end)[6]


def _directory_bounds(data: bytes, label: str) -> tuple[int, int, int, int]:
    """(directory start, its end (where the end record, or the ZIP64 one, starts), the
    members claimed, the directory's claimed size) of ``data``."""
    at = data.rfind(_END, max(0, len(data) - _END_FMT.size - 0xFFFF))
    if at < 0 or len(data) < at + _END_FMT.size:
        if data[:4] in (_LOCAL, _END):
            raise damaged(label, "its zip directory is missing")
        raise RunFileError(f"{label} is not a run file (not a zip archive): open a file "
                           "saved with Save run or --save-run (*.armlab-run.zip)")
    _, disk, cd_disk, on_disk, count, size, offset, _ = _END_FMT.unpack_from(data, at)
    end = at
    if 0xFFFF in (disk, cd_disk, on_disk, count) or 0xFFFFFFFF in (size, offset):
        loc = at - _LOCATOR_FMT.size
        if loc >= 0 and data[loc:loc + 4] == _LOCATOR64:
            _, disk64, where, disks = _LOCATOR_FMT.unpack_from(data, loc)
            if disk64 != 0 or disks > 1:
                raise _split(label)
            # the ZIP64 end record sits just before its locator (wherever its offset points)
            end = loc - _END64_FMT.size
            if end < 0 or data[end:end + 4] != _END64:
                raise damaged(label, "its ZIP64 end record is missing")
            (_, _, _, _, disk, cd_disk, on_disk, count, size, offset) = \
                _END64_FMT.unpack_from(data, end)
    if disk != 0 or cd_disk != 0 or on_disk != count:
        raise _split(label)
    if count > MAX_MEMBERS or size > MAX_DIRECTORY_BYTES:
        return 0, 0, count, size
    start = end - size
    if start < 0 or start - offset < 0:
        raise damaged(label, "its zip directory lies outside the file")
    return start, end, count, size


def _split(label: str) -> RunFileError:
    return RunFileError(f"{label} says it is one part of a zip split over several disks "
                        "(its end record's disk fields); run files are one part: refused, "
                        "it was not written by armlab")


def _central_entry(data: bytes, at: int, end: int, shift: int,
                   label: str) -> tuple[Member, int]:
    """The member whose directory entry starts at ``at`` (< ``end``), and where the next
    starts; ``shift`` is added to its local header's offset."""
    if at + _CENTRAL_FMT.size > end or data[at:at + 4] != _CENTRAL:
        raise damaged(label, "its zip directory is cut or malformed")
    (_, _, _, flags, method, _, _, crc, packed, size, n_name, n_extra, n_comment,
     _, _, _, offset) = _CENTRAL_FMT.unpack_from(data, at)
    name_at = at + _CENTRAL_FMT.size
    nxt = name_at + n_name + n_extra + n_comment
    if nxt > end:
        raise damaged(label, "its zip directory is cut or malformed")
    raw = data[name_at:name_at + n_name]
    extra = data[name_at + n_name:name_at + n_name + n_extra]
    name = _member_name(raw, flags, label)
    if 0xFFFFFFFF in (packed, size, offset):
        size, packed, offset = _zip64_sizes(extra, size, packed, offset, name, label)
    if flags & 0x1:
        raise RunFileError(f"{label}: {quote(name)} is encrypted; run files are never "
                           "encrypted, so it was not written by armlab")
    if method not in (STORED, DEFLATED):
        kind = METHOD_NAMES.get(method, f"method {method}")
        raise RunFileError(f"{label}: {quote(name)} is packed with {kind}; run files hold "
                           "only stored or deflated members: refused, it was not written "
                           "by armlab")
    return Member(name=name, method=method, flags=flags, crc=crc, packed=packed, size=size,
                  offset=offset + shift), nxt


def _zip64_sizes(extra: bytes, size: int, packed: int, offset: int, name: str,
                 label: str) -> tuple[int, int, int]:
    """(size, packed, offset) with those the directory marks 0xFFFFFFFF read from the ZIP64
    extra field."""
    at = 0
    while at + 4 <= len(extra):
        kind, length = struct.unpack_from("<HH", extra, at)
        body = extra[at + 4:at + 4 + length]
        at += 4 + length
        if kind != 1:
            continue
        values = [v for (v,) in struct.iter_unpack("<Q", body[:len(body) // 8 * 8])]
        out = []
        for value in (size, packed, offset):
            if value == 0xFFFFFFFF:
                if not values:
                    break
                value = values.pop(0)
            out.append(value)
        if len(out) == 3:
            return out[0], out[1], out[2]
    raise damaged(label, f"{quote(name)} lacks the ZIP64 sizes its directory entry needs")


def _member_name(raw: bytes, flags: int, label: str) -> str:
    """The member's name, refused if it holds a NUL or control character, is too long,
    or is a path that would land outside its folder."""
    if len(raw) > MAX_NAME_BYTES:
        raise RunFileError(f"{label} holds a member named with {len(raw)} bytes "
                           f"({quote(raw, 60)}); names in a run file are at most "
                           f"{MAX_NAME_BYTES}: refused, it was not written by armlab")
    try:
        name = raw.decode("utf-8" if flags & 0x800 else "cp437")
    except UnicodeDecodeError:
        raise RunFileError(f"{label} holds a member named {quote(raw)}, not UTF-8 as its "
                           "header says: refused, it was not written by armlab") from None
    if any(ord(c) < 32 or ord(c) == 127 for c in name):
        raise RunFileError(f"{label} holds a member named {quote(name)}, with a NUL or "
                           "another control character in it: refused, it was not written "
                           "by armlab, do not unpack it")
    parts = name.split("/")
    if name.startswith("/") or "\\" in name or _DRIVE.match(name) or ".." in parts:
        raise RunFileError(f"{label} holds a member named {quote(name)}, a path that would "
                           "land outside its folder (absolute, '..', a drive or a "
                           "backslash); refused: it was not written by armlab, do not "
                           "unpack it")
    return name


def _bomb(label: str, what: str, size: int, limit: int) -> RunFileError:
    return RunFileError(f"{label}: {what} would unpack to {size / 2**20:.1f} MiB, over the "
                        f"{limit / 2**20:.0f} MiB it may hold (a zip bomb, or far too long "
                        "a run); refused")


def check_size(member: Member, label: str, limit: int) -> None:
    """Refuse ``member`` if it declares more than ``limit`` bytes or over
    :data:`MAX_RATIO`:1 (past :data:`RATIO_FLOOR_BYTES`)."""
    if member.size > limit:
        raise _bomb(label, member.name, member.size, limit)
    if member.size > RATIO_FLOOR_BYTES and member.size > MAX_RATIO * max(member.packed, 1):
        raise RunFileError(
            f"{label}: {member.name} would unpack {member.packed} bytes to "
            f"{member.size / 2**20:.1f} MiB (over {MAX_RATIO}:1), the mark of a zip "
            "bomb; refused")


def iter_member(data: bytes, member: Member, label: str, *, limit: int) -> Iterator[bytes]:
    """``member``'s unpacked bytes in chunks of at most 1 MiB, never more than it declares
    (at most ``limit``); its end, length and CRC checked after the last chunk."""
    check_size(member, label, limit)
    start, stop = _data_span(data, member, label)
    view = memoryview(data)[start:stop]
    crc = 0
    if member.method == STORED:
        if member.packed != member.size:
            raise damaged(label, f"{member.name} is stored with two sizes")
        for at in range(0, len(view), _OUT_CHUNK):
            piece = bytes(view[at:at + _OUT_CHUNK])
            crc = zlib.crc32(piece, crc)
            yield piece
        produced = len(view)
    else:
        produced, crc = yield from _inflate(view, member, label)
    if produced != member.size:
        raise damaged(label, f"{member.name} is shorter than its declared size")
    if crc != member.crc:
        raise damaged(label, f"{member.name} fails its CRC check")


def _inflate(view: memoryview, member: Member, label: str
             ) -> Generator[bytes, None, tuple[int, int]]:
    """Deflate's output of ``view`` in chunks, stopped at the first byte past the declared
    size or past :data:`MAX_RATIO`:1; returns (bytes produced, CRC)."""
    d = zlib.decompressobj(-15)
    produced = crc = used = 0
    while not d.eof:
        if d.unconsumed_tail:
            feed: bytes | memoryview = d.unconsumed_tail
        elif used < len(view):
            feed = view[used:used + _IN_CHUNK]
            used += len(feed)
        else:
            raise damaged(label, f"{member.name}'s data ends before its deflate stream")
        try:
            piece = d.decompress(feed, _OUT_CHUNK)
        except zlib.error as e:
            raise damaged(label, f"{member.name}: {e}") from None
        produced += len(piece)
        consumed = used - len(d.unconsumed_tail)
        if produced > member.size:
            raise RunFileError(f"{label}: {member.name} unpacks to more than its declared "
                               f"{member.size} bytes; refused (a forged zip)")
        if produced > RATIO_FLOOR_BYTES and produced > MAX_RATIO * max(consumed, 1):
            raise RunFileError(f"{label}: {member.name} unpacks {consumed} bytes to over "
                               f"{produced / 2**20:.1f} MiB (over {MAX_RATIO}:1), the mark "
                               "of a zip bomb; refused")
        crc = zlib.crc32(piece, crc)
        if piece:
            yield piece
    return produced, crc


def _data_span(data: bytes, member: Member, label: str) -> tuple[int, int]:
    """Where ``member``'s packed bytes are, from its local header (checked against the
    directory)."""
    at = member.offset
    if at < 0 or at + _LOCAL_FMT.size > len(data) or data[at:at + 4] != _LOCAL:
        raise damaged(label, f"{member.name}'s local header is missing")
    _, _, flags, method, _, _, _, _, _, n_name, n_extra = _LOCAL_FMT.unpack_from(data, at)
    name_at = at + _LOCAL_FMT.size
    raw = data[name_at:name_at + n_name]
    if method != member.method or _member_name(raw, flags, label) != member.name:
        raise damaged(label, f"{member.name}'s local header disagrees with the directory")
    start = name_at + n_name + n_extra
    stop = start + member.packed
    if stop > len(data):
        raise damaged(label, f"{member.name}'s data is cut short")
    return start, stop


def read_member(data: bytes, member: Member, label: str, *, limit: int) -> bytes:
    """``member``'s bytes whole (see :func:`iter_member`)."""
    return b"".join(iter_member(data, member, label, limit=limit))
