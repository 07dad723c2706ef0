"""Mach-O files: a universal ("fat") file from thin slices, and what a file declares.

zig builds one thin Mach-O library per architecture and has no ``lipo``. FMI 2 has one
folder for macOS (``binaries/darwin64``), so its FMUs carry one universal file holding
the x86_64 and arm64 slices: a ``fat_header`` and one ``fat_arch`` per slice, big-endian,
each slice at an offset aligned to 2**14 bytes (as Apple's ``lipo`` writes them).

:func:`read` lists a file's slices with their architecture, file type, the libraries
they import (``LC_LOAD_DYLIB`` and kin) and their exported and undefined symbols (the
symbol table), for the tests that check the macOS binaries without a Mac.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

FAT_MAGIC = 0xCAFEBABE
MH_MAGIC_64 = 0xFEEDFACF
CPU_TYPES = {0x01000007: "x86_64", 0x0100000C: "arm64"}
MH_DYLIB = 6
#: log2 of a slice's alignment in a universal file (16 KiB, arm64's page size)
ALIGN = 14
LC_SYMTAB = 0x2
#: load commands holding the export trie (what dyld binds against)
LC_DYLD_INFO_ONLY = 0x80000022
LC_DYLD_EXPORTS_TRIE = 0x80000033
#: load commands that name a library the file needs
LC_DYLIBS = {0xC: "load", 0x80000018: "weak", 0x8000001F: "reexport", 0x80000023: "lazy"}


class MachOError(ValueError):
    """Not a (64-bit, little-endian) Mach-O file, or a malformed one."""


def _thin_header(data: bytes) -> tuple[int, int]:
    if len(data) < 32 or struct.unpack_from("<I", data, 0)[0] != MH_MAGIC_64:
        raise MachOError("not a 64-bit little-endian Mach-O slice")
    cputype, cpusubtype = struct.unpack_from("<iI", data, 4)
    return cputype & 0xFFFFFFFF, cpusubtype


def fat_binary(slices: list[bytes]) -> bytes:
    """One universal Mach-O file holding the thin ``slices`` (in that order)."""
    if not slices:
        raise MachOError("a universal file needs at least one slice")
    heads = [_thin_header(s) for s in slices]
    if len({cpu for cpu, _ in heads}) != len(heads):
        raise MachOError("two slices of the same architecture")
    step = 1 << ALIGN
    offset = 8 + 20 * len(slices)
    out = bytearray(struct.pack(">II", FAT_MAGIC, len(slices)))
    for (cpu, sub), data in zip(heads, slices):
        offset = -(-offset // step) * step
        out += struct.pack(">IIIII", cpu, sub, offset, len(data), ALIGN)
        offset += len(data)
    for data in slices:
        out += b"\0" * (-len(out) % step)
        out += data
    return bytes(out)


@dataclass(frozen=True)
class Slice:
    """What one architecture's slice declares."""

    arch: str
    filetype: int
    dylibs: tuple[str, ...]  # libraries it needs, in load order
    exports: frozenset[str]  # the export trie's symbols, without the leading '_'
    undefined: frozenset[str]  # external symbols it imports (the symbol table)


def _cstring(data: bytes, at: int) -> str:
    end = data.index(b"\0", at)
    return data[at:end].decode("utf-8", "replace")


def _uleb(data: bytes, at: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        byte = data[at]
        at += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if not byte & 0x80:
            return value, at


def _trie(data: bytes, start: int, size: int) -> set[str]:
    """The symbols of an export trie (``size`` bytes at ``start``)."""
    names: set[str] = set()
    todo = [(0, "")]
    seen = set()
    while todo:
        node, prefix = todo.pop()
        if node in seen or node >= size:
            raise MachOError("malformed export trie")
        seen.add(node)
        terminal, at = _uleb(data, start + node)
        if terminal:
            names.add(prefix)
        at += terminal
        count = data[at]
        at += 1
        for _ in range(count):
            end = data.index(b"\0", at)
            edge = data[at:end].decode("utf-8", "replace")
            child, at = _uleb(data, end + 1)
            todo.append((child, prefix + edge))
    return names


def _slice(data: bytes) -> Slice:
    cpu, _sub = _thin_header(data)
    filetype, ncmds, _sizeofcmds = struct.unpack_from("<III", data, 12)
    at = 32
    dylibs: list[str] = []
    exports: set[str] = set()
    undefined: set[str] = set()
    for _ in range(ncmds):
        cmd, size = struct.unpack_from("<II", data, at)
        if size < 8 or at + size > len(data):
            raise MachOError("malformed load command")
        if cmd in LC_DYLIBS:
            (name_off,) = struct.unpack_from("<I", data, at + 8)
            dylibs.append(_cstring(data, at + name_off))
        elif cmd == LC_DYLD_INFO_ONLY:
            export_off, export_size = struct.unpack_from("<II", data, at + 40)
            if export_size:
                exports |= _trie(data, export_off, export_size)
        elif cmd == LC_DYLD_EXPORTS_TRIE:
            export_off, export_size = struct.unpack_from("<II", data, at + 8)
            exports |= _trie(data, export_off, export_size)
        elif cmd == LC_SYMTAB:
            symoff, nsyms, stroff, _strsize = struct.unpack_from("<IIII", data, at + 8)
            for i in range(nsyms):
                strx, ntype, _nsect, _ndesc, _value = struct.unpack_from(
                    "<IBBhQ", data, symoff + 16 * i
                )
                if ntype & 0xE0 or not ntype & 0x01:  # debug entry, or not external
                    continue
                if ntype & 0x0E == 0x00:  # N_UNDF: imported
                    undefined.add(_cstring(data, stroff + strx))
        at += size
    arch = CPU_TYPES.get(cpu, f"cpu {cpu:#x}")

    def bare(names: set[str]) -> frozenset[str]:
        return frozenset(n[1:] if n.startswith("_") else n for n in names)

    return Slice(arch, filetype, tuple(dylibs), bare(exports), bare(undefined))


def read(data: bytes) -> list[Slice]:
    """The slices of a thin or universal Mach-O file."""
    if len(data) >= 8 and struct.unpack_from(">I", data, 0)[0] == FAT_MAGIC:
        (n,) = struct.unpack_from(">I", data, 4)
        slices = []
        for i in range(n):
            _cpu, _sub, offset, size, _align = struct.unpack_from(">IIIII", data, 8 + 20 * i)
            if offset + size > len(data):
                raise MachOError("a slice runs past the end of the file")
            slices.append(_slice(data[offset : offset + size]))
        return slices
    return [_slice(data)]
