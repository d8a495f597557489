#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
# Seeds for the splat format harnesses (fuzz/corpus/{splat,spz,compressed_ply}/): tiny files of
# each layout written from its public description (docs: README "Splat file formats"), so the
# fuzzer starts inside valid files. fuzz/make_corpus.sh runs it; it also runs on its own:
#   python3 fuzz/make_splat_corpus.py fuzz/corpus
import gzip
import os
import struct
import sys

out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "corpus")


def write(harness, name, data):
    os.makedirs(os.path.join(out, harness), exist_ok=True)
    with open(os.path.join(out, harness, name), "wb") as f:
        f.write(data)


# antimatter15 .splat: 32-byte records (float32 position, float32 scale, RGBA, rotation w x y z).
def splat_record(i):
    return struct.pack("<6f8B", 0.1 * i, -0.2 * i, 3.0 + i, 0.05, 0.1, 0.02, 200, 100, 50, 180, 255, 128, 128, 128)


write("splat", "two.splat", splat_record(0) + splat_record(1))
write("splat", "zero_rotation.splat", struct.pack("<6f8B", 0, 0, 1, 1, 1, 1, 0, 0, 0, 0, 128, 128, 128, 128))


# Niantic .spz v2/v3: gzip of a 16-byte header and the splats attribute by attribute (the raw
# stream; the harness or the writes below gzip it).
def spz(version, degree, n):
    dim = (degree + 1) ** 2 - 1
    body = b""
    for i in range(n):  # positions: 24-bit fixed point, 12 fractional bits
        for v in (0.5 * i, -0.25 * i, 2.0 + i):
            body += struct.pack("<i", int(v * 4096))[:3]
    body += bytes([128 + 10 * i for i in range(n)])                  # alphas
    body += bytes([100, 128, 160] * n)                               # colours
    body += bytes([100, 110, 120] * n)                               # scales
    if version >= 3:
        body += struct.pack("<I", (3 << 30) | (0 << 20) | (0 << 10) | 0) * n  # w largest: identity
    else:
        body += bytes([128, 128, 128] * n)
    body += bytes([128 + (k % 7) * 8 for k in range(dim * 3)]) * n  # SH
    return struct.pack("<IIIBBBB", 0x5053474E, version, n, degree, 12, 0, 0) + body


# Niantic .spz v4: a 32-byte header in the clear, a table of contents (compressed and uncompressed
# size per stream, uint64) and each non-empty attribute as its own ZSTD frame. The frames are
# written here from the Zstandard format (RFC 8878) without compressing: a single-segment frame
# header with a 4-byte content size, then one "raw" block (the bytes as they are, at most 128 kB);
# no checksum. So the fuzzer's mutations of a stream's bytes reach the attribute decoding directly,
# as the gzip harness's odd first byte does for v2/v3.
def zstd_frame(data):
    assert len(data) <= 128 * 1024
    frame = struct.pack("<IB", 0xFD2FB528, 0xA0) + struct.pack("<I", len(data))  # FCS 4 bytes, single segment
    return frame + struct.pack("<I", 1 | (0 << 1) | (len(data) << 3))[:3] + data  # block header: last, raw, size


def spz_v4(degree, n):
    legacy = spz(3, degree, n)  # v3 holds the same attribute bytes after its 16-byte header
    sizes = [9 * n, n, 3 * n, 3 * n, 4 * n, 3 * ((degree + 1) ** 2 - 1) * n]
    streams, at = [], 16
    for size in sizes:
        if size:
            streams.append(legacy[at:at + size])
        at += size
    frames = [zstd_frame(s) for s in streams]
    header = struct.pack("<IIIBBBBI12x", 0x5053474E, 4, n, degree, 12, 0, len(streams), 32)
    toc = b"".join(struct.pack("<QQ", len(f), len(s)) for f, s in zip(frames, streams))
    return header + toc + b"".join(frames)


# The harness reads the first byte: even = the rest is the file, odd = the rest is the decompressed
# stream of a v2/v3 file (the harness gzips it).
write("spz", "v4_sh0.spz", b"\x00" + spz_v4(0, 3))
write("spz", "v4_sh2.spz", b"\x00" + spz_v4(2, 2))
write("spz", "v3_sh0.spz", b"\x00" + gzip.compress(spz(3, 0, 3), mtime=0))
write("spz", "v3_sh1.spz", b"\x00" + gzip.compress(spz(3, 1, 2), mtime=0))
write("spz", "v2_sh2.spz", b"\x00" + gzip.compress(spz(2, 2, 2), mtime=0))
write("spz", "raw_v3_sh3.bin", b"\x01" + spz(3, 3, 2))
write("spz", "raw_v2_sh1.bin", b"\x01" + spz(2, 1, 3))


# PlayCanvas compressed.ply: chunk bounds, packed vertices, optional SH bytes. The harness reads
# the first byte: even = compressed.ply reader, odd = the dispatcher.
def compressed_ply(n, degree, chunk_colours=True):
    chunks = (n + 255) // 256
    chunk_props = ["min_x", "min_y", "min_z", "max_x", "max_y", "max_z",
                   "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z"]
    if chunk_colours:
        chunk_props += ["min_r", "min_g", "min_b", "max_r", "max_g", "max_b"]
    rest = 3 * ((degree + 1) ** 2 - 1)
    head = "ply\nformat binary_little_endian 1.0\nelement chunk %d\n" % chunks
    head += "".join("property float %s\n" % p for p in chunk_props)
    head += "element vertex %d\n" % n
    head += "".join("property uint %s\n" % p for p in ["packed_position", "packed_rotation", "packed_scale", "packed_color"])
    if rest:
        head += "element sh %d\n" % n + "".join("property uchar f_rest_%d\n" % j for j in range(rest))
    head += "end_header\n"
    bounds = [-1, -1, 2, 1, 1, 4, -5, -5, -5, -2, -2, -2] + ([0.1, 0.1, 0.1, 0.9, 0.9, 0.9] if chunk_colours else [])
    data = head.encode() + struct.pack("<%df" % len(bounds), *bounds) * chunks
    for i in range(n):
        position = (i * 97 % 2048) << 21 | (i * 31 % 1024) << 11 | (i * 13 % 2048)
        rotation = (0 << 30) | (512 << 20) | (600 << 10) | 400
        colour = (200 << 24) | (100 << 16) | (50 << 8) | 180
        data += struct.pack("<4I", position, rotation, position ^ 0x155555, colour)
    data += bytes([(17 * k) % 256 for k in range(rest)]) * n
    return data


write("compressed_ply", "sh0.ply", b"\x00" + compressed_ply(3, 0))
write("compressed_ply", "sh1_two_chunks.ply", b"\x00" + compressed_ply(257, 1))
write("compressed_ply", "old_chunks.ply", b"\x00" + compressed_ply(2, 0, chunk_colours=False))
write("compressed_ply", "dispatch.ply", b"\x01" + compressed_ply(2, 2))
