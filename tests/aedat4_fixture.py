"""Writes AEDAT 4.0 files for the tests, independently of evnerf: the flatbuffers through Debian's
python3-flatbuffers Builder (back to front, fields at their defaults left out, as flatc's code writes them),
packets compressed by python3-lz4 and python3-zstandard, from the published schemas (IOHeader, EventPacket,
Frame, ImuPacket, TriggerPacket, FileDataTable). Also reads a file's events back through the same library,
to check evnerf's writer.

Usage: aedat4_fixture.py write OUT_DIR      (files and the expected events; see write())
       aedat4_fixture.py read FILE OUT.txt  (the events of FILE as "t_us x y p" lines)
"""
import struct
import sys

import flatbuffers
import lz4.frame
import zstandard
from flatbuffers import table as fbtable

MAGIC = b"#!AER-DAT4.0\r\n"
W, H = 64, 48
ORIGIN_US = 1_700_000_123 * 1_000_000 + 250_000  # Unix time of the first event: origin 1700000123 s


def compress(kind, data):
    if kind == 0:
        return bytes(data)
    if kind == 1:
        return lz4.frame.compress(bytes(data))
    return zstandard.ZstdCompressor(level=3).compress(bytes(data))


def xml_for(streams):
    """The IOHeader's infoNode: (id, type, name, width, height) per stream."""
    out = ['<dv version="2.0">', ' <node name="outInfo" path="/mainloop/Recorder/outInfo/">']
    for sid, typ, name, w, h in streams:
        p = f"/mainloop/Recorder/outInfo/{sid}/"
        out += [f'  <node name="{sid}" path="{p}">',
                '   <attr key="compression" type="string">LZ4</attr>',
                '   <attr key="originalModuleName" type="string">capture</attr>',
                f'   <attr key="originalOutputName" type="string">{name}</attr>',
                f'   <attr key="typeDescription" type="string">Array of &lt;{name}&gt; &amp; more</attr>',
                f'   <attr key="typeIdentifier" type="string">{typ}</attr>']
        if w:
            out += [f'   <node name="info" path="{p}info/">',
                    f'    <attr key="sizeX" type="int">{w}</attr>',
                    f'    <attr key="sizeY" type="int">{h}</attr>',
                    '    <attr key="source" type="string">DAVIS346_00000499</attr>',
                    '   </node>']
        out.append('  </node>')
    out += [' </node>', '</dv>']
    return "\n".join(out)


def ioheader(compression, table_pos, xml):
    b = flatbuffers.Builder(1024)
    s = b.CreateString(xml)
    b.StartObject(3)
    b.PrependUOffsetTRelativeSlot(2, s, 0)
    b.PrependInt64Slot(1, table_pos, -1)
    b.PrependInt32Slot(0, compression, 0)
    b.FinishSizePrefixed(b.EndObject(), b"IOHE")
    return bytes(b.Output())


def event_packet(evs):
    b = flatbuffers.Builder(16 * len(evs) + 64)
    b.StartVector(16, len(evs), 8)
    for t, x, y, p in reversed(evs):
        b.Prep(8, 16)
        b.Pad(3)
        b.PrependBool(bool(p))
        b.PrependInt16(y)
        b.PrependInt16(x)
        b.PrependInt64(t)
    v = b.EndVector()
    b.StartObject(1)
    b.PrependUOffsetTRelativeSlot(0, v, 0)
    b.FinishSizePrefixed(b.EndObject(), b"EVTS")
    return bytes(b.Output())


def frame_packet(t, w, h, fmt, pixels, pos=(0, 0)):
    b = flatbuffers.Builder(len(pixels) + 128)
    pv = b.CreateByteVector(bytes(pixels))
    b.StartObject(11)
    b.PrependUOffsetTRelativeSlot(10, pv, 0)
    b.PrependInt16Slot(9, pos[1], 0)
    b.PrependInt16Slot(8, pos[0], 0)
    b.PrependInt16Slot(7, h, 0)
    b.PrependInt16Slot(6, w, 0)
    b.PrependInt8Slot(5, fmt, 0)
    for slot, v in ((4, t + 500), (3, t - 500), (2, t + 900), (1, t - 900), (0, t)):
        b.PrependInt64Slot(slot, v, 0)
    b.FinishSizePrefixed(b.EndObject(), b"FRME")
    return bytes(b.Output())


def imu_packet(t):
    b = flatbuffers.Builder(256)
    imus = []
    for k in range(3):
        b.StartObject(11)
        for slot in range(1, 11):
            b.PrependFloat32Slot(slot, 0.5 * slot + k, 0.0)
        b.PrependInt64Slot(0, t + k, 0)
        imus.append(b.EndObject())
    b.StartVector(4, len(imus), 4)
    for o in reversed(imus):
        b.PrependUOffsetTRelative(o)
    v = b.EndVector()
    b.StartObject(1)
    b.PrependUOffsetTRelativeSlot(0, v, 0)
    b.FinishSizePrefixed(b.EndObject(), b"IMUS")
    return bytes(b.Output())


def data_table(entries):
    """entries: (byte_offset, stream, size, count, t_begin, t_end)."""
    b = flatbuffers.Builder(64 * len(entries) + 64)
    defs = []
    for off, sid, size, n, t0, t1 in entries:
        b.StartObject(5)
        b.PrependInt64Slot(4, t1, 0)
        b.PrependInt64Slot(3, t0, 0)
        b.PrependInt64Slot(2, n, 0)
        b.Prep(4, 8)
        b.PrependInt32(size)
        b.PrependInt32(sid)
        b.PrependStructSlot(1, b.Offset(), 0)
        b.PrependInt64Slot(0, off, 0)
        defs.append(b.EndObject())
    b.StartVector(4, len(defs), 4)
    for d in reversed(defs):
        b.PrependUOffsetTRelative(d)
    v = b.EndVector()
    b.StartObject(1)
    b.PrependUOffsetTRelativeSlot(0, v, 0)
    b.FinishSizePrefixed(b.EndObject(), b"FTAB")
    return bytes(b.Output())


def aedat4(path, compression, packets, streams, with_table=True):
    """packets: (stream, flatbuffer bytes, count, t_begin, t_end) in file order."""
    xml = xml_for(streams)
    head = len(MAGIC) + len(ioheader(compression, 0, xml))
    body, entries = bytearray(), []
    for sid, fb, n, t0, t1 in packets:
        c = compress(compression, fb)
        entries.append((head + len(body), sid, len(c), n, t0, t1))
        body += struct.pack("<ii", sid, len(c)) + c
    table_pos = head + len(body) if with_table else -1
    out = MAGIC + ioheader(compression, table_pos, xml) + body
    if with_table:
        out += compress(compression, data_table(entries))
    open(path, "wb").write(out)
    return entries


def lcg(seed):
    while True:
        seed = (seed * 6364136223846793005 + 1442695040888963407) % 2**64
        yield seed >> 33


def write(out):
    rnd = lcg(2024)
    evs, t = [], ORIGIN_US
    while len(evs) < 6000:
        t += next(rnd) % 400 if next(rnd) % 80 else 150_000  # now and then a pause
        evs.append((t, next(rnd) % W, next(rnd) % H, next(rnd) % 2))
    frames = []  # a grey frame every 40 ms, a BGR one among them, a region-of-interest frame to skip
    for k, ft in enumerate(range(ORIGIN_US + 20_000, evs[-1][0], 40_000)):
        px = bytes((x * 3 + y * 5 + k) % 256 for y in range(H) for x in range(W))
        frames.append((ft, frame_packet(ft, W, H, 0, px)))
    roi = frame_packet(frames[1][0] + 1, 16, 8, 0, bytes(16 * 8), pos=(4, 4))
    bgr_t = frames[2][0] + 2
    bgr = frame_packet(bgr_t, W, H, 16, bytes(v for y in range(H) for x in range(W) for v in (10, 20 + x, 30 + y)))
    streams = [(0, "EVTS", "events", W, H), (1, "FRME", "frames", W, H), (2, "IMUS", "imu", 0, 0), (3, "TRIG", "triggers", 0, 0)]
    packets, f, i, n, frame_times = [], 0, 0, 0, []
    sizes = [1, 7, 300, 1000, 2500]
    extra = [(frames[1][0] + 1, roi), (bgr_t, bgr)]
    while i < len(evs):
        k = min(sizes[n % len(sizes)], len(evs) - i)
        chunk = evs[i:i + k]
        while f < len(frames) and frames[f][0] <= chunk[0][0]:
            packets.append((1, frames[f][1], 1, frames[f][0], frames[f][0]))
            frame_times.append(frames[f][0])
            for et, fb in list(extra):
                if frames[f][0] <= et <= frames[f][0] + 5:
                    packets.append((1, fb, 1, et, et))
                    extra.remove((et, fb))
                    if fb is bgr:
                        frame_times.append(et)
            f += 1
        packets.append((0, event_packet(chunk), k, chunk[0][0], chunk[-1][0]))
        if n % 3 == 0:
            packets.append((2, imu_packet(chunk[0][0]), 3, chunk[0][0], chunk[0][0] + 2))
        i += k
        n += 1
    origin = ORIGIN_US // 1_000_000 * 1_000_000
    with open(f"{out}/expected.txt", "w") as fh:
        fh.writelines(f"{(t - origin) / 1e6:.9f} {x} {y} {p}\n" for t, x, y, p in evs)
    assert not extra
    with open(f"{out}/expected_frames.txt", "w") as fh:
        fh.writelines(f"{(ft - origin) / 1e6:.9f}\n" for ft in frame_times)
    aedat4(f"{out}/lz4.aedat4", 1, packets, streams, with_table=False)
    aedat4(f"{out}/zstd.aedat4", 3, packets, streams, with_table=True)
    aedat4(f"{out}/none.aedat4", 0, packets, streams, with_table=True)
    # Small bad files: time running backwards, a coordinate outside the sensor, no sensor size, a corrupt packet.
    aedat4(f"{out}/backwards.aedat4", 0, [(0, event_packet([(ORIGIN_US + 10, 1, 1, 1), (ORIGIN_US + 5, 2, 2, 0)]), 2, 0, 0)],
           streams[:1], with_table=False)
    aedat4(f"{out}/outside.aedat4", 0, [(0, event_packet([(ORIGIN_US, 1, 1, 1), (ORIGIN_US + 5, W, 2, 0)]), 2, 0, 0)], streams[:1],
           with_table=False)
    aedat4(f"{out}/nosize.aedat4", 1, [(0, event_packet(evs[:10]), 10, 0, 0)], [(0, "EVTS", "events", 0, 0)], with_table=False)
    aedat4(f"{out}/corrupt.aedat4", 1, [(0, event_packet(evs[:500]), 500, 0, 0)], streams[:1], with_table=False)
    data = bytearray(open(f"{out}/corrupt.aedat4", "rb").read())
    head = len(MAGIC) + struct.unpack_from("<I", data, len(MAGIC))[0] + 4
    for k in range(head + 8 + 20, head + 8 + 60):
        data[k] ^= 0x5A
    open(f"{out}/corrupt.aedat4", "wb").write(data)
    with open(f"{out}/corrupt_at.txt", "w") as fh:
        fh.write(f"{head}\n")
    open(f"{out}/calib.txt", "w").write("60 60 32 24 0 0 0 0 0\n")
    # Poses in the file's clock (Unix seconds), as a motion-capture system beside the camera writes them.
    with open(f"{out}/groundtruth.txt", "w") as fh:
        for k in range(140):
            fh.write(f"{origin / 1e6 + 0.1 * k:.6f} {0.01 * k:.6f} 0 0 0 0 0 1\n")


def read(path, out):
    """The events of an AEDAT4 file, read by python3-flatbuffers' Table from the schema."""
    data = open(path, "rb").read()
    assert data[:14] == MAGIC
    n = struct.unpack_from("<I", data, 14)[0]
    hb = bytearray(data[18:18 + n])
    h = fbtable.Table(hb, flatbuffers.encode.Get(flatbuffers.packer.uoffset, hb, 0))
    o = h.Offset(4)
    compression = h.Get(flatbuffers.number_types.Int32Flags, o + h.Pos) if o else 0
    o = h.Offset(6)
    table_pos = h.Get(flatbuffers.number_types.Int64Flags, o + h.Pos) if o else -1
    xml = h.String(h.Offset(8) + h.Pos).decode()
    assert 'typeIdentifier" type="string">EVTS' in xml
    end = table_pos if table_pos >= 0 else len(data)
    pos, lines = 18 + n, []
    while pos < end:
        sid, size = struct.unpack_from("<ii", data, pos)
        raw = data[pos + 8: pos + 8 + size]
        pos += 8 + size
        if sid != 0:
            continue
        fb = lz4.frame.decompress(raw) if compression in (1, 2) else zstandard.ZstdDecompressor().decompress(raw) if compression in (3, 4) else raw
        fb = bytearray(fb[4:])
        assert fb[4:8] == b"EVTS"
        t = fbtable.Table(fb, flatbuffers.encode.Get(flatbuffers.packer.uoffset, fb, 0))
        vo = t.Offset(4)
        start, count = t.Vector(vo), t.VectorLen(vo)
        for k in range(count):
            us, x, y, p = struct.unpack_from("<qhh?", fb, start + 16 * k)
            lines.append(f"{us} {x} {y} {int(p)}\n")
    open(out, "w").writelines(lines)


if __name__ == "__main__":
    if sys.argv[1] == "write":
        write(sys.argv[2])
    else:
        read(sys.argv[2], sys.argv[3])
