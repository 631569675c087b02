#!/usr/bin/env python3
"""Writes the seed corpus under fuzz/corpus/<target>/ (the files are committed; run this only to
change them). Files named found_* are reproducers of findings, copied in by hand, and kept. Real
points are cut from data/kitti_raw_seq_a/0000000000.bin (see corpus/README.md).
Usage: fuzz/make_seeds.py  (from anywhere; plain Python 3, no packages)."""
import math
import pathlib
import shutil
import struct

ROOT = pathlib.Path(__file__).resolve().parent.parent
CORPUS = ROOT / "fuzz" / "corpus"
SCAN = ROOT / "data" / "kitti_raw_seq_a" / "0000000000.bin"

NAN = float("nan")
INF = float("inf")


def real_points(first, count):
    """`count` KITTI points (x, y, z, reflectance) of the bundled scan from index `first`."""
    data = SCAN.read_bytes()
    return [struct.unpack_from("<4f", data, 16 * i) for i in range(first, first + count)]


def floats(values):
    return struct.pack("<%df" % len(values), *values)


def write(target, name, data):
    path = CORPUS / target / name
    path.write_bytes(data.encode() if isinstance(data, str) else data)


# ---- KITTI and nuScenes: headerless float32 records ------------------------------------------

def kitti(points):
    return b"".join(floats(p) for p in points)


def nuscenes(points):
    return b"".join(floats(p[:4]) + floats([float(i % 32)]) for i, p in enumerate(points))


def float_record_seeds(target, encode, record):
    scan = real_points(10000, 200)
    write(target, "empty", b"")
    write(target, "real_200_points", encode(scan))
    write(target, "one_point", encode(scan[:1]))
    write(target, "truncated_last_record", encode(scan[:3])[:-5])
    write(target, "size_not_multiple_of_record", encode(scan[:2]) + b"\x01\x02\x03")
    write(target, "one_byte_short_of_a_record", b"\x00" * (record - 1))
    write(target, "nan_and_inf", encode([(NAN, 1.0, 2.0, 0.0), (1.0, INF, 2.0, 0.0), (1.0, 2.0, -INF, 0.0),
                                         (1.0, 2.0, 3.0, NAN)] + scan[:4]))
    write(target, "coordinates_1e30", encode([(1e30, -1e30, 1e30, 0.5), (3.4e38, -3.4e38, 0.0, 1.0)] + scan[:2]))
    write(target, "all_nan", encode([(NAN, NAN, NAN, NAN)] * 4))
    write(target, "denormals_and_negative_zero", encode([(1e-45, -0.0, 1e-40, -1e-45)] * 3))


# ---- PCD -------------------------------------------------------------------------------------

def pcd_header(fields="x y z intensity", size="4 4 4 4", type_="F F F F", count="1 1 1 1", width=None,
               height=1, points=0, data="ascii", viewpoint=True):
    width = points if width is None else width
    lines = ["# .PCD v0.7 - Point Cloud Data file format", "VERSION 0.7", "FIELDS " + fields, "SIZE " + size,
             "TYPE " + type_, "COUNT " + count, "WIDTH %s" % width, "HEIGHT %s" % height]
    if viewpoint:
        lines.append("VIEWPOINT 0 0 0 1 0 0 0")
    lines += ["POINTS %s" % points, "DATA " + data]
    return "\n".join(lines) + "\n"


def ascii_body(points):
    return "".join("%r %r %r %r\n" % tuple(p) for p in points)


def lzf_literals(data):
    """LZF with literal runs only (control byte n < 32: n + 1 literal bytes follow)."""
    out = bytearray()
    for i in range(0, len(data), 32):
        chunk = data[i:i + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)


def compressed(points, fields=4):
    """binary_compressed body: the fields one after another (x of every point, then y, ...)."""
    raw = b"".join(floats([p[f] for p in points]) for f in range(fields))
    block = lzf_literals(raw)
    return struct.pack("<II", len(block), len(raw)) + block


def pcd_seeds():
    t = "fuzz_pcd"
    scan = real_points(20000, 100)
    write(t, "empty", b"")
    write(t, "ascii_30_points", pcd_header(points=30) + ascii_body(scan[:30]))
    write(t, "binary_100_points", pcd_header(points=100, data="binary").encode() + kitti(scan))
    write(t, "binary_compressed_60_points",
          pcd_header(points=60, data="binary_compressed").encode() + compressed(scan[:60]))
    # Ten copies of one point: each field's run is a literal value and a back reference to it.
    raw = b"".join(floats([v]) * 10 for v in scan[0])
    block = b"".join(bytes([3]) + floats([v]) + bytes([7 << 5, 36 - 2 - 7, 4 - 1]) for v in scan[0])
    write(t, "binary_compressed_back_reference",
          pcd_header(points=10, data="binary_compressed").encode() + struct.pack("<II", len(block), len(raw)) + block)
    write(t, "binary_compressed_with_padding_field_last",
          pcd_header(fields="x y z _", points=8, data="binary_compressed").encode() + compressed(scan[:8], fields=3))
    write(t, "binary_compressed_with_padding_field_inside",
          pcd_header(fields="x _ y z", points=8, data="binary_compressed").encode() + compressed(scan[:8], fields=3))
    write(t, "binary_with_padding_field", pcd_header(fields="x _ y z", points=4, data="binary").encode() +
          kitti([(p[0], 0.0, p[1], p[2]) for p in scan[:4]]))
    write(t, "ascii_xyz_only", pcd_header("x y z", "4 4 4", "F F F", "1 1 1", points=3) +
          "".join("%r %r %r\n" % p[:3] for p in scan[:3]))
    write(t, "ascii_crlf", (pcd_header(points=3) + ascii_body(scan[:3])).replace("\n", "\r\n"))
    write(t, "ascii_without_count_and_viewpoint",
          "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n")
    write(t, "binary_double_and_integer_fields",
          pcd_header("x y z intensity", "8 8 8 2", "F F F U", points=2, data="binary").encode() +
          struct.pack("<dddH", 1.5, -2.5, 0.25, 7) + struct.pack("<dddH", 1e300, -1e300, 3.0, 65535))
    write(t, "binary_int8_and_int64_fields",
          pcd_header("x y z intensity", "1 2 8 4", "I I I U", points=2, data="binary").encode() +
          struct.pack("<bhqI", -128, -32768, -(2 ** 63), 2 ** 32 - 1) + struct.pack("<bhqI", 127, 32767, 2 ** 63 - 1, 0))
    write(t, "field_with_count_3", pcd_header("x y z normal", "4 4 4 4", "F F F F", "1 1 1 3", points=2,
                                              data="binary").encode() + floats(list(range(12))))
    write(t, "count_mismatch_points_vs_width", pcd_header(width=4, points=5) + ascii_body(scan[:5]))
    write(t, "count_mismatch_height_zero", pcd_header(width=3, height=0, points=3) + ascii_body(scan[:3]))
    write(t, "ascii_fewer_lines_than_points", pcd_header(points=10) + ascii_body(scan[:7]))
    write(t, "ascii_more_lines_than_points", pcd_header(points=2) + ascii_body(scan[:5]))
    write(t, "ascii_wrong_value_count", pcd_header(points=2) + "1 2 3\n4 5 6 7\n")
    write(t, "ascii_not_a_number", pcd_header(points=1) + "1 2 abc 4\n")
    write(t, "binary_truncated", pcd_header(points=10, data="binary").encode() + kitti(scan[:10])[:-8])
    write(t, "binary_trailing_garbage", pcd_header(points=2, data="binary").encode() + kitti(scan[:2]) + b"junk")
    write(t, "binary_trailing_zero_padding", pcd_header(points=2, data="binary").encode() + kitti(scan[:2]) +
          b"\0" * 16)
    write(t, "binary_compressed_truncated",
          pcd_header(points=20, data="binary_compressed").encode() + compressed(scan[:20])[:-9])
    write(t, "binary_compressed_size_mismatch",
          pcd_header(points=21, data="binary_compressed").encode() + compressed(scan[:20]))
    write(t, "binary_compressed_huge_sizes",
          pcd_header(points=4, data="binary_compressed").encode() + struct.pack("<II", 0xFFFFFFFF, 64) + b"\x1f" * 40)
    write(t, "points_uint64_max", pcd_header(width=18446744073709551615, points=18446744073709551615, data="binary")
          .encode() + kitti(scan[:2]))
    write(t, "points_2_pow_32_plus_1", pcd_header(width=4294967297, points=4294967297, data="binary").encode() +
          kitti(scan[:1]))
    write(t, "width_huge_times_height_wraps_to_zero",
          pcd_header(width=4294967296, height=4294967296, points=0, data="binary"))
    write(t, "width_times_height_wraps_to_one",
          pcd_header(width=3, height=0xAAAAAAAAAAAAAAAB, points=1, data="binary").encode() + kitti(scan[:1]))
    write(t, "count_huge", pcd_header("x y z intensity", "4 4 4 4", "F F F F", "1 1 1 4294967297", points=1,
                                      data="binary").encode() + kitti(scan[:1]))
    write(t, "size_huge", pcd_header("x y z intensity", "4 4 4 18446744073709551615", points=1,
                                     data="binary").encode() + kitti(scan[:1]))
    write(t, "ascii_nan_and_inf", pcd_header(points=4) + "nan 1 2 0\n1 inf 2 0\n1 2 -inf 0\n1 2 3 nan\n")
    write(t, "ascii_1e30_and_1e39", pcd_header(points=3) + "1e30 -1e30 1e30 0\n1e39 0 0 0\n-1e39 1e-50 0 0\n")
    write(t, "binary_nan_inf_1e30", pcd_header(points=3, data="binary").encode() +
          kitti([(NAN, 0.0, 0.0, 0.0), (INF, -INF, 0.0, 0.0), (1e30, -1e30, 3.4e38, 0.0)]))
    write(t, "zero_points_binary", pcd_header(points=0, data="binary"))
    write(t, "header_without_data_line", pcd_header(points=1).replace("DATA ascii\n", ""))
    write(t, "header_only_data_at_end_of_file", pcd_header(points=1).rstrip("\n"))
    write(t, "no_z_field", pcd_header("x y intensity", "4 4 4", "F F F", "1 1 1", points=1) + "1 2 3\n")
    write(t, "unknown_data_kind", pcd_header(points=1, data="binary_scrambled") + "1 2 3 4\n")
    write(t, "whitespace_only_header_line", pcd_header(points=1).replace("VERSION 0.7\n", "VERSION 0.7\n\r\n") +
          "1 2 3 4\n")
    # PCL sized its buffer at POINTS from the fields read so far, then wrote 200-value points into it.
    write(t, "count_after_points_overflowed_pcl",
          "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 8\nCOUNT 1 1 200\nDATA ascii\n" +
          (" ".join(["1"] * 202) + "\n") * 8)
    write(t, "size_after_points", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nSIZE 8 8 8\nDATA ascii\n1 2 3\n")
    write(t, "fields_twice", "FIELDS a b\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA ascii\n1 2 3\n")
    write(t, "points_twice", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n")
    write(t, "fields_after_points", "POINTS 1\nWIDTH 1\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nDATA ascii\n1 2 3\n")


# ---- uploads: protobuf wire encoding of fogmap.v1 ----------------------------------------------

def varint(v):
    v &= (1 << 64) - 1
    out = bytearray()
    while True:
        byte = v & 0x7F
        v >>= 7
        if v:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


def field_varint(number, v):
    return varint(number << 3) + varint(v)


def field_bytes(number, data):
    return varint((number << 3) | 2) + varint(len(data)) + data


def packed_varints(number, values):
    return field_bytes(number, b"".join(varint(v) for v in values)) if values else b""


def packed_floats(number, values):
    return field_bytes(number, floats(values)) if values else b""


EPOCH = 17_000_000_000      # the harness clock starts at the start of this epoch (100 ms epochs)
START_NS = 1_700_000_000_000_000_000


def header(node, epoch=EPOCH, sensor_time_ns=START_NS + 5_000_000, contributing=(), missing=(), failed=(),
           dropped=0):
    return (field_varint(1, node) + field_varint(2, epoch) + field_varint(3, sensor_time_ns) +
            packed_varints(4, contributing) + packed_varints(5, missing) + packed_varints(6, failed) +
            (field_varint(7, dropped) if dropped else b""))


def ellipsoid(node, index, center, shape=(0.25, 0.0, 0.0, 0.25, 0.0, 0.25), point_count=20, frame=None):
    eid = field_varint(1, node) + (field_varint(2, frame) if frame is not None else b"") + field_varint(3, index)
    return field_bytes(1, eid) + packed_floats(2, center) + packed_floats(3, shape) + field_varint(4, point_count)


def map_object(*ellipsoids):
    return b"".join(field_bytes(1, e) for e in ellipsoids)


def map_upload(sequence, hdr, objects, blocks=(), packed_objects=0):
    """A Map upload: `objects` listed (those with exact ellipsoids), `packed_objects` objects after them
    whose ellipsoids are all records."""
    body = field_bytes(1, hdr) + b"".join(field_bytes(2, o) for o in objects) + b"".join(
        field_bytes(3, b) for b in blocks) + (field_varint(4, packed_objects) if packed_objects else b"")
    return field_varint(1, sequence) + field_bytes(2, body)


def zigzag(v):
    return v << 1 if v >= 0 else ((-v) << 1) - 1


def record(offset_cm, semi_axes_mm, point_count, index, rotation=(1.0, 0.0, 0.0, 0.0), word=None):
    """One 22-byte compact ellipsoid record (common/geometry/compact_ellipsoid.hpp): the centre in cm
    from the block's origin, semi-axes in mm (ascending), the rotation as a unit quaternion (w, x, y, z)
    in "smallest three" form, or `word`, the 48-bit orientation word as is."""
    if word is None:
        c = list(rotation)
        dropped = max(range(4), key=lambda i: abs(c[i]))
        if c[dropped] < 0:
            c = [-v for v in c]
        step = math.sqrt(2) / 2 / 16383
        word = dropped << 45
        kept = [v for i, v in enumerate(c) if i != dropped]
        for slot, v in enumerate(kept):
            word |= min(max(round(v / step) + 16383, 0), 32766) << (15 * slot)
    return (struct.pack("<3h3H", *offset_cm, *semi_axes_mm) + word.to_bytes(6, "little") +
            struct.pack("<HH", point_count, index))


def block(node, origin_cm, records, frame=None, object_of=(), steps=None, first_index=None):
    """An EllipsoidBlock: the records of one (node, frame) around origin_cm; object_of (the object of
    each record) goes on the wire as steps from the previous record's (sint32, zigzag), or `steps` as
    given; both empty makes each record an object of its own. With first_index, each record's last
    2 bytes (its index) are left out and the block numbers them from first_index."""
    if steps is None:
        steps = [o - p for o, p in zip(object_of, [0] + list(object_of[:-1]))]
    if first_index is not None:
        records = [r[:20] if len(r) == 22 else r for r in records]
    return (field_varint(1, node) + (field_varint(2, frame) if frame is not None else b"") +
            b"".join(field_varint(3 + i, zigzag(v)) for i, v in enumerate(origin_cm)) +
            field_bytes(6, b"".join(records)) + packed_varints(7, [zigzag(v) for v in steps]) +
            (field_varint(9, first_index) if first_index is not None else b""))


def chunk_upload(sequence, hdr, points, chunk=0, chunk_count=1, first_point=0, total_points=None, labels=None):
    total_points = len(points) if total_points is None else total_points
    body = (field_bytes(1, hdr) + field_varint(2, chunk) + field_varint(3, chunk_count) +
            field_varint(4, first_point) + field_varint(5, total_points) +
            field_bytes(6, b"".join(floats(p[:3]) for p in points)))
    if labels is not None:
        body += field_bytes(7, struct.pack("<%di" % len(labels), *labels))
    return field_varint(1, sequence) + field_bytes(3, body)


MADC, BASELINE, EXT = 0, 1, 2
INTERMEDIATE = 4


def stream_input(config, *records):
    """records: (stream, ticks of 10 ms before the upload, close after it, upload bytes)."""
    out = bytearray([config])
    for stream, ticks, close, upload in records:
        out.append(stream | (ticks << 2) | (0x80 if close else 0))
        out += struct.pack("<H", len(upload)) + upload
    return bytes(out)


def upload_seeds():
    t = "fuzz_upload"
    scan = real_points(10000, 240)
    e1 = ellipsoid(1, 0, (10.0, -2.6, 0.2))
    e1b = ellipsoid(1, 1, (34.5, -8.0, 0.3), (1.0, 0.2, 0.0, 0.5, 0.0, 0.1), 55)
    e2 = ellipsoid(2, 0, (10.3, -2.5, 0.2))            # meets e1: merged into one object
    e3 = ellipsoid(3, 0, (10.6, -2.6, 0.25))
    e4 = ellipsoid(4, 0, (-20.0, 5.0, 0.0), (4.0, 0.0, 0.0, 4.0, 0.0, 1.0))
    next_epoch = EPOCH + 1
    write(t, "empty", b"")
    write(t, "config_only", bytes([MADC]))
    # Maps for the next epoch from every child, then the clock passes its start: one merge, one emit.
    write(t, "valid_maps_star_and_subtree", stream_input(
        MADC,
        (0, 0, False, map_upload(1, header(1, next_epoch), [map_object(e1), map_object(e1b)])),
        (1, 0, False, map_upload(1, header(2, next_epoch), [map_object(e2)])),
        (2, 0, False, map_upload(1, header(101, next_epoch, contributing=(3, 4)),
                                 [map_object(ellipsoid(3, 0, (10.6, -2.6, 0.25), frame=next_epoch),
                                             ellipsoid(4, 0, (-20.0, 5.0, 0.0), frame=next_epoch))])),
        (0, 12, False, map_upload(2, header(1, next_epoch + 1), [map_object(e1)]))))
    write(t, "intermediate_maps", stream_input(
        MADC | INTERMEDIATE,
        (0, 0, False, map_upload(7, header(3), [map_object(e3)])),
        (1, 0, False, map_upload(9, header(4, failed=(4,)), [])),
        (1, 25, True, map_upload(10, header(4, next_epoch), [map_object(e4)]))))
    write(t, "late_map_becomes_revision", stream_input(
        MADC,
        (0, 0, False, map_upload(1, header(1), [map_object(e1)])),
        (1, 20, False, map_upload(1, header(2), [map_object(e2)])),
        (1, 1, False, map_upload(1, header(2), [map_object(e2)])),             # re-sent copy
        (1, 1, False, map_upload(1, header(2), [map_object(e1b)]))))           # same sequence, other content
    write(t, "nan_centre", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [map_object(
        ellipsoid(1, 0, (NAN, 0.0, 0.0)))]))))
    write(t, "inf_shape", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [map_object(
        ellipsoid(1, 0, (1.0, 0.0, 0.0), (INF, 0.0, 0.0, 1.0, 0.0, 1.0)))]))))
    write(t, "shape_not_positive_definite", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [map_object(
        ellipsoid(1, 0, (1.0, 0.0, 0.0), (1.0, 2.0, 0.0, 1.0, 0.0, 1.0)))]))))
    write(t, "shape_ill_conditioned", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [map_object(
        ellipsoid(1, 0, (1.0, 0.0, 0.0), (1e8, 0.0, 0.0, 1e-9, 0.0, 1e-9)))]))))
    write(t, "shape_wrong_value_count", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [map_object(
        ellipsoid(1, 0, (1.0, 0.0, 0.0), (1.0, 0.0, 1.0)))]))))
    write(t, "centre_1e30_out_of_world", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [map_object(
        ellipsoid(1, 0, (1e30, -1e30, 0.0)))]))))
    write(t, "huge_epoch", stream_input(MADC, (0, 0, False, map_upload(1, header(1, 2 ** 64 - 1), [map_object(e1)])),
                                        (0, 0, False, map_upload(2, header(1, 2 ** 63), [map_object(e1)])),
                                        (0, 0, False, map_upload(3, header(1, 0), [map_object(e1)]))))
    write(t, "unknown_node", stream_input(MADC, (0, 0, False, map_upload(1, header(7), [map_object(
        ellipsoid(7, 0, (1.0, 0.0, 0.0)))]))))
    write(t, "forged_node_on_stream", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [map_object(e1)])),
                                                   (0, 0, False, map_upload(2, header(2), [map_object(e2)])),
                                                   (0, 0, False, map_upload(3, header(1), [map_object(e2)]))))
    many = [map_object(ellipsoid(1, k, (float(k), 0.0, 0.0), (0.01, 0.0, 0.0, 0.01, 0.0, 0.01), 2 ** 64 - 1))
            for k in range(65)]
    write(t, "huge_ellipsoid_count", stream_input(MADC, (0, 0, False, map_upload(1, header(1), many))))
    write(t, "duplicate_ellipsoid_id", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [
        map_object(e1), map_object(e1)]))))
    write(t, "ellipsoid_conflict_across_uploads", stream_input(
        MADC, (0, 0, False, map_upload(1, header(1, next_epoch), [map_object(e1)])),
        (0, 0, False, map_upload(2, header(1, next_epoch), [map_object(ellipsoid(1, 0, (11.0, -2.6, 0.2)))])),
        (0, 0, False, map_upload(3, header(1, next_epoch), [map_object(e1, e1b)]))))
    write(t, "upload_without_payload", stream_input(MADC, (0, 0, False, field_varint(1, 5)),
                                                    (0, 0, False, map_upload(1, b"", [map_object(e1)]))))
    write(t, "points_in_madc_mode", stream_input(MADC, (0, 0, False, chunk_upload(1, header(1), scan[:10]))))
    # Baseline root: two sensors' scans in chunks (one relayed through agg) cluster centrally.
    write(t, "baseline_chunks", stream_input(
        BASELINE,
        (0, 0, False, chunk_upload(1, header(1, next_epoch), scan[:60], 0, 2, 0, 100)),
        (0, 0, False, chunk_upload(2, header(1, next_epoch), scan[60:100], 1, 2, 60, 100)),
        (1, 0, False, chunk_upload(1, header(2, next_epoch), scan[100:180])),
        (2, 0, False, chunk_upload(1, header(3, next_epoch), scan[180:240])),
        (1, 12, False, chunk_upload(2, header(2, next_epoch + 1), [(1e30, 0.0, 0.0, 0.0)]))))
    write(t, "baseline_chunks_that_do_not_tile", stream_input(
        BASELINE,
        (0, 0, False, chunk_upload(1, header(1), scan[:30], 0, 2, 0, 50)),
        (0, 0, False, chunk_upload(2, header(1), scan[30:50], 1, 2, 25, 50)),
        (0, 0, False, chunk_upload(3, header(1), scan[:30], 0, 3, 0, 50)),
        (0, 0, False, chunk_upload(4, header(1), scan[:30], 5, 2, 0, 50)),
        (0, 0, False, chunk_upload(5, header(1), scan[:30], 0, 1, 4294967295, 4294967295))))
    write(t, "baseline_intermediate_relays", stream_input(
        BASELINE | INTERMEDIATE,
        (0, 0, False, chunk_upload(1, header(3), scan[:40])),
        (1, 0, False, map_upload(1, header(4), [map_object(e4)]))))
    # ext root: maps and labelled chunks; the labels name local clusters 0 and 1 and noise.
    labels = [(-1 if k % 7 == 0 else k % 2) for k in range(40)]
    write(t, "ext_maps_and_labels", stream_input(
        EXT,
        (0, 0, False, map_upload(1, header(1, next_epoch), [map_object(e1), map_object(e1b)])),
        (0, 0, False, chunk_upload(2, header(1, next_epoch), scan[:40], labels=labels)),
        (1, 0, False, chunk_upload(1, header(2, next_epoch), scan[40:60], labels=[0] * 20)),
        (1, 0, False, chunk_upload(2, header(2, next_epoch + 1), scan[40:60], labels=[0] * 19)),
        (0, 15, False, map_upload(3, header(1, next_epoch + 1), []))))
    write(t, "chunk_xyz_not_multiple_of_12", stream_input(BASELINE, (0, 0, False, (
        field_varint(1, 1) + field_bytes(3, field_bytes(1, header(1)) + field_varint(3, 1) +
                                         field_varint(5, 1) + field_bytes(6, b"\0" * 13))))))
    write(t, "stream_closed_and_reopened", stream_input(
        MADC,
        (0, 0, True, map_upload(1, header(1, next_epoch), [map_object(e1)])),
        (1, 5, False, map_upload(1, header(2, next_epoch), [map_object(e2)])),
        (2, 30, False, map_upload(2, header(1, next_epoch + 3), [map_object(e1)]))))


# ---- topologies --------------------------------------------------------------------------------

def topology_seeds():
    t = "fuzz_topology"
    for name in ("star-2.yaml", "tree-7.yaml"):
        shutil.copyfile(ROOT / "topologies" / name, CORPUS / t / name.replace(".yaml", ""))
    small = """name: small
mode: %(mode)s
nodes:
  - {name: sink, id: 100, role: aggregator, host: 127.0.0.1, port: 50000, metrics_port: 50200}
  - name: edge-1
    id: 1
    role: edge
    parent: %(parent)s
    host: 127.0.0.1
    metrics_port: %(metrics)s
    sensor:
      source: scans
      rate_hz: 10
      frames: 5
      split: {views: 4, index: 1, overlap_deg: 10}
      pose: {translation_m: [1, 2, 0.5], rpy_deg: [0, 5, 90]}
"""
    write(t, "small_star_with_pose", small % {"mode": "madc", "parent": "sink", "metrics": 50101})
    write(t, "baseline_mode", small % {"mode": "baseline", "parent": "sink", "metrics": 50101})
    write(t, "duplicate_port", small % {"mode": "madc", "parent": "sink", "metrics": 50000})
    write(t, "unknown_parent", small % {"mode": "madc", "parent": "nowhere", "metrics": 50101})
    write(t, "edge_as_parent", small % {"mode": "madc", "parent": "edge-1", "metrics": 50101})
    write(t, "cycle", """nodes:
  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}
  - {name: a, id: 101, role: aggregator, parent: b, port: 50001, metrics_port: 50201}
  - {name: b, id: 102, role: aggregator, parent: a, port: 50002, metrics_port: 50202}
  - {name: e, id: 1, role: edge, parent: a, metrics_port: 50101, sensor: {source: s}}
""")
    write(t, "own_parent", """nodes:
  - {name: sink, id: 100, role: aggregator, parent: sink, port: 50000, metrics_port: 50200}
""")
    write(t, "two_roots_duplicate_ids", """nodes:
  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}
  - {name: sink2, id: 100, role: aggregator, port: 50001, metrics_port: 50201}
""")
    write(t, "missing_fields", """nodes:
  - {name: sink, role: aggregator}
  - {id: 1, role: edge, parent: sink}
  - {name: e2, id: 2, parent: sink, metrics_port: 1}
""")
    write(t, "edge_without_sensor", """nodes:
  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}
  - {name: e, id: 1, role: edge, parent: sink, metrics_port: 50101}
""")
    write(t, "absurd_numbers", """name: absurd
deadline_ms: 1e308
period_ms: -1
max_message_bytes: 99999999999999999999
max_scan_bytes: -5
admission: {window_periods: 1e300, world_extent_m: .inf, max_ellipsoids_per_map: 18446744073709551615,
            max_map_bytes: 0, min_eigenvalue_m2: 1e-300, max_eigenvalue_m2: 1e300, max_condition: .nan}
madc: {eps_m: 1e-9, min_points: 9223372036854775807, alpha: 1e20, threads: 100000}
preprocess:
  crop: {min_m: [.nan, 0, 0], max_m: [1e308, 1e308, 1e308]}
  voxel_leaf_m: -0.0
  ground: {distance_threshold_m: 1e-320, max_tilt_deg: 90, ground_z_hint_m: .inf}
nodes:
  - {name: sink, id: 4294967296, role: aggregator, host: 999.1.1.1, port: 70000, metrics_port: -1}
  - name: e
    id: -1
    role: edge
    parent: sink
    metrics_port: 65535
    sensor: {source: s, rate_hz: .inf, frames: 18446744073709551616, split: {views: 1000000, index: -1,
             overlap_deg: 1e400}, pose: {translation_m: [1e308, -1e308, 0], rpy_deg: [1e300, .nan, 0]}}
""")
    write(t, "absurd_but_in_range", """name: edge-of-range
deadline_ms: 60000
period_ms: 1e-6
admission: {window_periods: 1e300, world_extent_m: 1e300, max_ellipsoids_per_map: 9223372036854775807,
            max_map_bytes: 1, min_eigenvalue_m2: 1e-300, max_eigenvalue_m2: 1e300, max_condition: 1e300}
madc: {eps_m: 100, min_points: 2147483647, alpha: 9.99, threads: 256}
nodes:
  - {name: sink, id: 4294967295, role: aggregator, host: 255.255.255.255, port: 65535, metrics_port: 1}
  - {name: e, id: 0, role: edge, parent: sink, host: 0.0.0.0, metrics_port: 65535,
     sensor: {source: /, rate_hz: 1000, frames: 9223372036854775807,
              split: {views: 64, index: 63, overlap_deg: 5.6}, pose: {rpy_deg: [1e15, -1e15, 360]}}}
""")
    write(t, "not_a_mapping", "- just\n- a\n- list\n")
    write(t, "unknown_key", "nodes: []\nwhatever: 1\n")
    write(t, "empty", "")
    write(t, "invalid_yaml", "nodes: [ {name: sink, id: 100\n  role: : :\n\t- ]]\n")
    write(t, "deep_nesting", "nodes: " + "[" * 3000 + "]" * 3000 + "\n")
    write(t, "aliases", "a: &x {name: n, id: 1}\nnodes: [*x, *x, *x]\nname: *x\n")
    write(t, "wrong_types", "name: [1, 2]\nmode: {a: b}\nperiod_ms: fast\nnodes: {a: 1}\n")
    write(t, "host_names_and_nul", "nodes:\n  - {name: sink, id: 1, role: aggregator, host: localhost, port: 1,"
                                   " metrics_port: 2}\n  - {name: \"e\\0x\", id: 2, role: aggregator,"
                                   " host: \"127.0.0.1\\0evil\", port: 3, metrics_port: 4, parent: sink}\n")
    write(t, "cameras_and_tracker", """name: fusion
nodes:
  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}
  - {name: edge-1, id: 1, role: edge, parent: sink, metrics_port: 50101, sensor: {source: sim, scene: s.yaml, lidar: l1}}
  - name: tracker
    id: 300
    role: tracker
    port: 50300
    metrics_port: 50301
    tracker: {association: paper, eps_sync_s: 0.1, rho_overlay_m: 5, max_detection_wait_s: 0.25}
  - name: cam-1
    id: 401
    role: detection
    parent: tracker
    metrics_port: 50401
    camera:
      source: sim
      scene: s.yaml
      camera: c1
      detector: {kind: truth, truth: {miss_rate: 0.3, box_jitter_px: 2, latency_ms: 40}}
      calibration: {fx: 500, fy: 500, cx: 320, cy: 240, width: 640, height: 480, distortion: [0.1, 0, 0, 0, 0],
                    pose: {translation_m: [-20, 0, 2], rpy_deg: [-90, 0, -90]}}
  - name: cam-2
    id: 402
    role: detection
    parent: tracker
    metrics_port: 50402
    camera:
      source: images
      detector: {kind: dnn, dnn: {model_path: m.onnx, names_path: n.txt, output: yolo-export, mean: [0, 0, 0]}}
      calibration: {fx: 500, fy: 500, cx: 320, cy: 240, width: 640, height: 480}
""")
    write(t, "centroids_to_tracker", """name: centroids
nodes:
  - {name: sink, id: 100, role: aggregator, port: 50000, metrics_port: 50200}
  - name: edge-1
    id: 1
    role: edge
    parent: sink
    metrics_port: 50101
    sensor: {source: sim, scene: s.yaml, lidar: l1}
    displacement: {tracker: tracker, preset: outdoor, min_points: 6}
  - name: edge-2
    id: 2
    role: edge
    parent: sink
    metrics_port: 50102
    sensor: {source: scans}
    displacement: {tracker: tracker, voxel_m: 0.1, neighbour_m: 1.0, min_neighbours: 3, min_points: 6, min_z_variance_m2: 0.01}
  - name: tracker
    id: 300
    role: tracker
    port: 50300
    metrics_port: 50301
    tracker: {input: centroids, centroid_merge_m: 1.0, association: kalman}
  - name: cam-1
    id: 401
    role: detection
    parent: tracker
    metrics_port: 50401
    camera:
      source: images
      calibration: {fx: 500, fy: 500, cx: 320, cy: 240, width: 640, height: 480}
""")

    # What fogctl up --dry-run and compose make of accepted topologies (the target's project
    # directory holds scans/, images/, s.yaml, cascade.xml, m.onnx, m.cfg and n.txt).
    fusion = """name: %(name)s
nodes:
  - {name: %(root)s, id: 100, role: aggregator, port: 50000, metrics_port: 50200}
  - {name: edge-1, id: 1, role: edge, parent: %(root)s, metrics_port: 50101, sensor: {source: %(scans)s}}
  - {name: tracker, id: 300, role: tracker, port: 50300, metrics_port: 50301}
  - name: cam-1
    id: 401
    role: detection
    parent: tracker
    metrics_port: 50401
    camera:
      source: %(source)s
      detector: %(detector)s
      calibration: {fx: 500, fy: 500, cx: 320, cy: 240, width: 640, height: 480}
%(more)s"""
    dnn_camera = """  - name: cam-2
    id: 402
    role: detection
    parent: tracker
    metrics_port: 50402
    camera:
      source: images
      detector: {kind: dnn, dnn: {model_path: m.onnx, config_path: m.cfg, names_path: n.txt, output: ssd}}
      calibration: {fx: 500, fy: 500, cx: 320, cy: 240, width: 640, height: 480}
"""

    def camera_seed(name, detector, source="images", scans="scans", root="sink", more=""):
        write(t, name, fusion % {"name": name.replace("_", "-"), "detector": detector, "source": source, "scans": scans,
                                 "root": root, "more": more})

    camera_seed("cascade_without_path", "{kind: cascade}")
    camera_seed("cascade_section_without_path", "{kind: cascade, cascade: {label: face, min_neighbors: 2}}")
    camera_seed("cascade_path_empty", "{kind: cascade, cascade: {cascade_path: ''}}")
    camera_seed("cascade_path_missing_file", "{kind: cascade, cascade: {cascade_path: no-such.xml}}")
    camera_seed("dnn_without_names", "{kind: dnn, dnn: {model_path: m.onnx}}")
    camera_seed("deployable_cascade_and_dnn", "{kind: cascade, cascade: {cascade_path: cascade.xml, scale_factor: 1.2}}",
                more=dnn_camera)
    camera_seed("cascade_bad_scale_factor", "{kind: cascade, cascade: {cascade_path: cascade.xml, scale_factor: 7}}")
    camera_seed("camera_device_hog", "{kind: hog}", source="/dev/video0")
    camera_seed("camera_source_missing", "{kind: hog}", source="no-such-frames")
    camera_seed("scans_outside_the_project", "{kind: hog}", scans="/no/such/scans")
    camera_seed("node_named_prometheus", "{kind: hog}", root="prometheus")
    write(t, "tls_ca_beside_the_topology", small % {"mode": "madc", "parent": "sink", "metrics": 50101} +
          "tls: {ca: ca.crt, geofence_clients: [operator]}\n")


def compact_upload_seeds():
    """Maps whose ellipsoids travel as compact records in blocks (protos/fogmap/v1 EllipsoidBlock)."""
    t = "fuzz_upload"
    next_epoch = EPOCH + 1
    yaw_30 = (math.cos(math.radians(15)), 0.0, 0.0, math.sin(math.radians(15)))
    # Node 1's clusters around (10.0, -2.6, 0.2) (e1 of upload_seeds) and (34.5, -8.0, 0.3).
    r1 = record((0, 0, 0), (500, 500, 500), 20, 0)
    r1b = record((2450, -540, 10), (300, 700, 1000), 55, 1, yaw_30)
    r2 = record((0, 0, 0), (400, 500, 600), 20, 0)                         # node 2 at (10.3, -2.5, 0.2)
    r3 = record((0, 0, 0), (450, 500, 550), 20, 0)                         # node 3 at (10.6, -2.6, 0.25)
    r4 = record((0, 0, 0), (1000, 2000, 2000), 20, 0, (0.5, 0.5, 0.5, 0.5))  # node 4 at (-20.0, 5.0, 0.0)
    e1 = ellipsoid(1, 0, (10.0, -2.6, 0.2))
    # Local maps as one block without objects, an intermediate's map listing the object of each record.
    write(t, "packed_maps_star_and_subtree", stream_input(
        MADC,
        (0, 0, False, map_upload(1, header(1, next_epoch), [], [block(1, (1000, -260, 20), [r1, r1b])])),
        (1, 0, False, map_upload(1, header(2, next_epoch), [], [block(2, (1030, -250, 20), [r2])])),
        (2, 0, False, map_upload(1, header(101, next_epoch, contributing=(3, 4)), [],
                                 [block(3, (1060, -260, 25), [r3], frame=next_epoch, object_of=[0]),
                                  block(4, (-2000, 500, 0), [r4], frame=next_epoch, object_of=[0])],
                                 packed_objects=1)),
        (0, 12, False, map_upload(2, header(1, next_epoch + 1), [], [block(1, (1000, -260, 20), [r1])]))))
    write(t, "packed_intermediate_relays_records", stream_input(
        MADC | INTERMEDIATE,
        (0, 0, False, map_upload(7, header(3), [], [block(3, (1060, -260, 25), [r3])])),
        (1, 0, False, map_upload(9, header(4), [], [block(4, (-2000, 500, 0), [r4, record((-150, 80, 3), (300, 310, 320), 9, 1)])])),
        (1, 25, True, map_upload(10, header(4, EPOCH + 3), [], [block(4, (-2000, 500, 0), [r4])]))))
    # An object with an exact ellipsoid (an 80 m semi-axis does not fit a record) and a record.
    long_axis = ellipsoid(1, 2, (12.0, -2.6, 0.2), (6400.0, 0.0, 0.0, 0.25, 0.0, 0.25))
    write(t, "packed_and_exact_in_one_object", stream_input(
        MADC, (0, 0, False, map_upload(1, header(1), [map_object(long_axis)],
                                       [block(1, (1000, -260, 20), [r1], object_of=[0]),
                                        block(1, (3450, -800, 30), [record((0, 0, 0), (300, 700, 1000), 55, 1)])]))))
    write(t, "packed_ellipsoid_conflict_across_uploads", stream_input(
        MADC,
        (0, 0, False, map_upload(1, header(1, next_epoch), [], [block(1, (1000, -260, 20), [r1])])),
        (0, 0, False, map_upload(2, header(1, next_epoch), [], [block(1, (1000, -260, 20), [r1])])),   # same again
        (0, 0, False, map_upload(3, header(1, next_epoch), [map_object(e1)], [])),                      # as exact
        (0, 0, False, map_upload(4, header(1, next_epoch), [], [block(1, (1001, -260, 20), [r1])]))))  # moved 1 cm
    write(t, "packed_65_records", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (0, 0, 0), [record((100 * k, 0, 0), (10, 10, 10), 3, k) for k in range(65)])]))))
    write(t, "packed_origin_at_int32_limits", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (2 ** 31 - 1, -2 ** 31, 0), [record((32767, -32767, 0), (500, 500, 500), 20, 0)]),
        block(1, (0, 0, 0), [record((-32768, 32767, -32768), (1, 1, 65535), 65535, 1)])]))))
    # An edge's local map whose block numbers its records (20 bytes each, indices 0, 1).
    write(t, "packed_first_index_local_map", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (1000, -260, 20), [r1, r1b], first_index=0)]))))
    # Malformed blocks and records: refused naming the block and record.
    write(t, "block_first_index_past_the_last_index", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (1000, -260, 20), [r1, r1b], first_index=2 ** 32 - 1)]))))
    write(t, "block_records_not_multiple_of_20_with_first_index", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (1000, -260, 20), [r1, r1b, b"\x01"], first_index=3)]))))
    write(t, "block_records_not_multiple_of_22", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (1000, -260, 20), [r1, b"\x01"])]))))
    write(t, "block_object_of_out_of_range", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (1000, -260, 20), [r1, r1b], steps=[0, 2 ** 31 - 1])], packed_objects=1))))
    write(t, "block_object_step_below_zero", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (1000, -260, 20), [r1, r1b], steps=[1, -2])], packed_objects=2))))
    write(t, "packed_objects_above_records", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (1000, -260, 20), [r1, r1b], object_of=[0, 1])], packed_objects=2 ** 32 - 1))))
    write(t, "block_object_of_length_mismatch", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (1000, -260, 20), [r1, r1b], object_of=[0])], packed_objects=1))))
    write(t, "block_object_left_empty", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [
        map_object()], [block(1, (1000, -260, 20), [r1, r1b], object_of=[1, 1])], packed_objects=1))))
    write(t, "record_zero_semi_axis", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (1000, -260, 20), [r1, record((0, 0, 0), (0, 500, 500), 20, 1)])]))))
    write(t, "record_reserved_orientation_bit", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (1000, -260, 20), [record((0, 0, 0), (500, 500, 500), 20, 0, word=(1 << 47) | (16383 * 0x40008001))])]))))
    write(t, "record_quaternion_norm_above_1", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (1000, -260, 20), [record((0, 0, 0), (500, 500, 500), 20, 0, word=(3 << 45) | (2 ** 45 - 1)),
                                    record((5, 5, 5), (500, 600, 700), 20, 1, word=(1 << 45) | (32766 * 0x40008001))])]))))
    write(t, "duplicate_id_exact_and_record", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [
        map_object(e1)], [block(1, (1000, -260, 20), [r1])]))))
    write(t, "duplicate_record_in_two_blocks", stream_input(MADC, (0, 0, False, map_upload(1, header(1), [], [
        block(1, (1000, -260, 20), [r1]), block(1, (0, 0, 0), [record((1000, -260, 20), (500, 500, 500), 20, 0)])]))))


def main():
    for target in ("fuzz_kitti", "fuzz_nuscenes", "fuzz_pcd", "fuzz_upload", "fuzz_topology"):
        directory = CORPUS / target
        directory.mkdir(parents=True, exist_ok=True)
        for seed in directory.iterdir():
            if not seed.name.startswith("found_"):  # reproducers of findings are kept as they are
                seed.unlink()
    float_record_seeds("fuzz_kitti", kitti, 16)
    float_record_seeds("fuzz_nuscenes", nuscenes, 20)
    pcd_seeds()
    upload_seeds()
    compact_upload_seeds()
    topology_seeds()
    assert all(p.stat().st_size <= 8192 for p in CORPUS.rglob("*") if p.is_file()), "seeds stay small"


if __name__ == "__main__":
    main()
