"""The universal Mach-O writer and reader (glider_fmi.macho), and the toolchain's platform
names, on synthetic files (the real dylibs: tests/integration/test_platforms.py)."""

from __future__ import annotations

import struct

import pytest

from glider_fmi import macho, toolchain


def thin(cputype: int, subtype: int, size: int, fill: bytes) -> bytes:
    """A minimal 64-bit Mach-O dylib: header with no load commands, padded."""
    head = struct.pack("<IiIIIIII", macho.MH_MAGIC_64, cputype, subtype, macho.MH_DYLIB, 0, 0, 0, 0)
    return head + fill * (size - len(head))


X86 = thin(0x01000007, 3, 5000, b"x")
ARM = thin(0x0100000C, 0, 70000, b"a")


def test_fat_header_and_slices_big_endian_and_aligned():
    fat = macho.fat_binary([X86, ARM])
    magic, n = struct.unpack_from(">II", fat, 0)
    assert (magic, n) == (0xCAFEBABE, 2)
    archs = [struct.unpack_from(">IIIII", fat, 8 + 20 * i) for i in range(n)]
    assert [(a[0], a[1]) for a in archs] == [(0x01000007, 3), (0x0100000C, 0)]
    assert [a[4] for a in archs] == [14, 14]
    assert [a[2] for a in archs] == [16384, 16384 * 2]  # 5000 bytes fit in one 16 KiB step
    for (_cpu, _sub, offset, size, _align), data in zip(archs, [X86, ARM]):
        assert offset % (1 << 14) == 0
        assert fat[offset : offset + size] == data
    assert len(fat) == archs[1][2] + len(ARM)
    assert [s.arch for s in macho.read(fat)] == ["x86_64", "arm64"]
    assert [s.arch for s in macho.read(ARM)] == ["arm64"]  # a thin file reads as one slice


def test_fat_binary_refuses_what_is_no_slice():
    with pytest.raises(macho.MachOError, match="same architecture"):
        macho.fat_binary([X86, X86])
    with pytest.raises(macho.MachOError, match="not a 64-bit"):
        macho.fat_binary([X86, b"\x7fELF" + bytes(60)])
    with pytest.raises(macho.MachOError, match="at least one"):
        macho.fat_binary([])
    with pytest.raises(macho.MachOError, match="past the end"):
        macho.read(macho.fat_binary([X86, ARM])[:-1])


@pytest.mark.parametrize(
    ("triple", "key"),
    [
        ("x86_64-linux-gnu", "x86_64-linux"),
        ("aarch64-linux-gnu", "aarch64-linux"),
        ("x86_64-w64-mingw32", "x86_64-windows"),
        ("x86_64-apple-darwin23.0.0", "x86_64-darwin"),
        ("arm64-apple-darwin23.0.0", "aarch64-darwin"),
        ("riscv64-linux-gnu", None),
        ("x86_64-unknown-freebsd14", None),
    ],
)
def test_a_compilers_target_names_our_platform(triple, key):
    assert toolchain._platform_of(triple) == key


def test_zig_is_the_default_and_builds_every_platform(monkeypatch):
    monkeypatch.delenv(toolchain.COMPILER_ENV, raising=False)
    chain = toolchain.select()
    assert [c.name for c in chain.compilers] == ["zig"]
    assert all(chain.for_platform(k).is_zig for k in toolchain.PLATFORMS)
    assert chain.compilers[0].argv(toolchain.PLATFORMS["x86_64-linux"])[-2:] == [
        "-target",
        "x86_64-linux-gnu.2.17",
    ]
    with pytest.raises(toolchain.ToolchainError, match="^--compiler no-such-cc: not found"):
        toolchain.select("no-such-cc")
