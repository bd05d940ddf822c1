#!/usr/bin/env python3
"""An OpenIGTLink device written from the public protocol description alone, not with the
OpenIGTLink library and not with incise's code: what a 3D Slicer or PLUS user's client does.

It plays a blade path (incise's CSV: t,tip_x,tip_y,tip_z,base_x,base_y,base_z in s and m) as
TRANSFORM messages in header version 1 or 2 (protocol 3: extended header, content, metadata
header, metadata; the CRC over all of them), reads everything the server sends, and checks it
as an independent reader would:
  - every message's CRC-64 (ECMA-182, computed here) and, for header version 2, its extended
    header and metadata sizes, which must fill the body exactly;
  - replies come in the header version the client speaks;
  - POLYDATA is parsed as the protocol lays it out, attributes sized by their type as the
    reference C reader sizes them (and point attributes only, which every reader sizes right);
  - every surface received is a closed 2-manifold: each edge used by exactly two triangles,
    once in each direction (counted here, not by incise's check), and no triangle with two
    corners at one place or no area.

Usage: igtl_spec_client.py PATH.csv --port P [--header-version 1|2] [--rate 500] [--hold 0.5]
Prints a JSON summary; exits 1 when anything failed a check.
"""

import argparse
import json
import math
import select
import socket
import struct
import sys
import time

HEADER_SIZE = 58
CRC_POLYNOMIAL = 0x42F0E1EBA9EA3693


def _crc_table():
    table = []
    for byte in range(256):
        crc = byte << 56
        for _ in range(8):
            crc = ((crc << 1) ^ CRC_POLYNOMIAL) if crc & (1 << 63) else (crc << 1)
            crc &= 0xFFFFFFFFFFFFFFFF
        table.append(crc)
    return table


_TABLE = _crc_table()


def crc64(data):
    """CRC-64 of ECMA-182, most significant bit first, from 0, as OpenIGTLink's header holds."""
    crc = 0
    for byte in data:
        crc = _TABLE[((crc >> 56) ^ byte) & 0xFF] ^ ((crc << 8) & 0xFFFFFFFFFFFFFFFF)
    return crc


def pack_message(type_name, device, timestamp, content, version, message_id=0, metadata=()):
    """A whole message: the 58-byte header and its body (header.md; version 3 description)."""
    if version == 2:
        keys = b"".join(k.encode() + v.encode() for k, v in metadata)
        meta_header = struct.pack(">H", len(metadata)) + b"".join(
            struct.pack(">HHI", len(k.encode()), 3, len(v.encode())) for k, v in metadata)
        extended = struct.pack(">HHII", 12, len(meta_header), len(keys), message_id)
        body = extended + content + meta_header + keys
    else:
        body = content
    header = struct.pack(">H12s20sQQQ", version, type_name.encode(), device.encode(), timestamp,
                         len(body), crc64(body))
    return header + body


def timestamp_of(seconds):
    whole = int(seconds)
    return (whole << 32) | int((seconds - whole) * 4294967296.0)


def transform_content(tip_mm, rotation):
    """TRANSFORM's content: R11 R21 R31 R12 R22 R32 R13 R23 R33 TX TY TZ (float32, mm)."""
    values = [rotation[row][column] for column in range(3) for row in range(3)] + list(tip_mm)
    return struct.pack(">12f", *values)


def rotation_from_z(direction):
    """The smallest rotation taking +z to the unit vector `direction` (Rodrigues)."""
    x, y, z = direction
    if z < -1.0 + 1e-12:
        return [[1, 0, 0], [0, -1, 0], [0, 0, -1]]
    # axis = z x d = (-y, x, 0); R = I + [v]x + [v]x^2 / (1 + c)
    vx, vy, c = -y, x, z
    k = 1.0 / (1.0 + c)
    return [[1 - k * vy * vy, k * vx * vy, vy],
            [k * vx * vy, 1 - k * vx * vx, -vx],
            [-vy, vx, c]]


def read_path(path):
    poses = []
    with open(path) as stream:
        header = stream.readline().strip()
        assert header == "t,tip_x,tip_y,tip_z,base_x,base_y,base_z", header
        for line in stream:
            if line.strip():
                poses.append([float(v) for v in line.split(",")])
    return poses


def pose_at(poses, t):
    if t <= poses[0][0]:
        return poses[0]
    for a, b in zip(poses, poses[1:]):
        if t <= b[0]:
            s = 0.0 if b[0] == a[0] else (t - a[0]) / (b[0] - a[0])
            return [a[k] + s * (b[k] - a[k]) for k in range(7)]
    return poses[-1]


class Checks:
    def __init__(self, version):
        self.version = version
        self.counts = {}
        self.failures = []
        self.surfaces = 0
        self.closed_surfaces = 0
        self.largest_edge_use = 0
        self.cut_share_max = 0.0
        self.forces = 0
        self.largest_force = 0.0
        self.statuses = []

    def fail(self, what):
        if len(self.failures) < 50:
            self.failures.append(what)

    def message(self, header, body):
        version, type_raw, device_raw, stamp, body_size, crc = struct.unpack(">H12s20sQQQ", header)
        type_name = type_raw.rstrip(b"\0").decode("ascii", "replace")
        self.counts[type_name] = self.counts.get(type_name, 0) + 1
        if crc64(body) != crc:
            self.fail(f"{type_name}: CRC mismatch")
            return
        if version != self.version:
            self.fail(f"{type_name}: header version {version}, the client speaks {self.version}")
        content = body
        if version == 2:
            if len(body) < 12:
                self.fail(f"{type_name}: body shorter than an extended header")
                return
            ext_size, meta_header_size, meta_size, _ = struct.unpack(">HHII", body[:12])
            if ext_size < 12 or ext_size + meta_header_size + meta_size > len(body):
                self.fail(f"{type_name}: extended header sizes overrun the body")
                return
            content = body[ext_size:len(body) - meta_header_size - meta_size]
            meta = body[len(body) - meta_header_size - meta_size:]
            if meta_header_size >= 2:
                (count,) = struct.unpack(">H", meta[:2])
                if meta_header_size != 2 + 8 * count:
                    self.fail(f"{type_name}: metadata header of {meta_header_size} bytes for "
                              f"{count} entries")
        elif version != 1:
            self.fail(f"{type_name}: header version {version}")
            return
        if type_name == "SENSOR":
            self.sensor(content)
        elif type_name == "POLYDATA":
            self.polydata(content)
        elif type_name == "STATUS":
            code = struct.unpack(">H", content[:2])[0]
            text = content[30:].split(b"\0")[0].decode("ascii", "replace")
            self.statuses.append((code, text))

    def sensor(self, content):
        length = content[0]
        if len(content) != 10 + 8 * length:
            self.fail("SENSOR: body size does not fit its length")
            return
        values = struct.unpack(f">{length}d", content[10:])
        self.forces += 1
        self.largest_force = max(self.largest_force, math.sqrt(sum(v * v for v in values)))

    def polydata(self, content):
        if len(content) < 40:
            self.fail("POLYDATA: shorter than its header")
            return
        (npoints, _, size_vertices, _, size_lines, npolygons, size_polygons, _, size_strips,
         nattributes) = struct.unpack(">10I", content[:40])
        at = 40
        if 40 + 12 * npoints + size_vertices + size_lines + size_polygons > len(content):
            self.fail("POLYDATA: counts run past the message")
            return
        flat = struct.unpack_from(f">{3 * npoints}f", content, at)
        points = list(zip(flat[0::3], flat[1::3], flat[2::3]))
        at += 12 * npoints + size_vertices + size_lines
        if size_polygons != 16 * npolygons:
            self.fail("POLYDATA: polygons that are not all triangles")
            return
        cells = struct.unpack_from(f">{4 * npolygons}I", content, at)
        at += size_polygons
        triangles = list(zip(cells[1::4], cells[2::4], cells[3::4]))
        if any(n != 3 for n in cells[0::4]) or any(max(t) >= npoints for t in triangles):
            self.fail("POLYDATA: a polygon that is not a triangle of its points")
            return
        at += size_strips
        headers = [struct.unpack(">BBI", content[at + 6 * i: at + 6 * i + 6])
                   for i in range(nattributes)]
        at += 6 * nattributes
        names = []
        names_start = at
        for _ in range(nattributes):
            stop = content.index(b"\0", at)
            names.append(content[at:stop].decode("ascii", "replace"))
            at = stop + 1
        if (at - names_start) % 2 == 1:
            at += 1
        for (kind, components, count), name in zip(headers, names):
            # The reference reader's sizes: scalar = its components, normal/vector 3,
            # tensor 9, RGBA 4; point attributes per point, cell ones per cell.
            per_item = {0: components, 1: 3, 2: 3, 3: 9, 4: 4}.get(kind & 0x0F)
            if kind & 0xF0 != 0:
                self.fail(f"POLYDATA: attribute {name} is a cell attribute (type {kind:#x}), "
                          "which the reference C reader sizes wrongly")
                return
            if per_item is None or count != npoints:
                self.fail(f"POLYDATA: attribute {name} of type {kind:#x} has {count} items "
                          f"for {npoints} points")
                return
            values = struct.unpack(f">{per_item * count}f", content[at:at + 4 * per_item * count])
            at += 4 * per_item * count
            if name == "CutFace":
                if any(not (0.0 <= v <= 1.0) for v in values):
                    self.fail("POLYDATA: CutFace outside [0, 1]")
                self.cut_share_max = max([self.cut_share_max] + list(values))
        if at != len(content):
            self.fail(f"POLYDATA: {len(content) - at} bytes left after the attributes")
            return
        self.surfaces += 1
        self.check_closed_manifold(points, triangles)

    def check_closed_manifold(self, points, triangles):
        uses = {}
        flat = 0
        for a, b, c in triangles:
            if len({a, b, c}) < 3 or len({points[a], points[b], points[c]}) < 3:
                flat += 1
            else:
                u = [points[b][k] - points[a][k] for k in range(3)]
                v = [points[c][k] - points[a][k] for k in range(3)]
                cross = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                         u[0] * v[1] - u[1] * v[0]]
                if cross == [0.0, 0.0, 0.0]:
                    flat += 1
            for p, q in ((a, b), (b, c), (c, a)):
                key = (min(p, q), max(p, q))
                forward, backward = uses.get(key, (0, 0))
                uses[key] = (forward + 1, backward) if p < q else (forward, backward + 1)
        bad = [key for key, (f, b) in uses.items() if (f, b) != (1, 1)]
        self.largest_edge_use = max([self.largest_edge_use] + [f + b for f, b in uses.values()])
        if bad or flat:
            self.fail(f"POLYDATA: not a closed 2-manifold: {len(bad)} edges not used once each "
                      f"way (largest use {max(f + b for f, b in uses.values())}), {flat} flat "
                      "triangles")
        else:
            self.closed_surfaces += 1


def run(path, port, version, rate=500.0, hold=0.5, host="127.0.0.1", device="Scalpel"):
    poses = read_path(path)
    deadline = time.monotonic() + 10.0
    while True:
        try:
            connection = socket.create_connection((host, port), timeout=1.0)
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.05)
    connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    connection.setblocking(False)
    checks = Checks(version)
    received = []
    buffer = b""
    start = time.monotonic()
    duration = poses[-1][0] - poses[0][0] + hold
    period = 1.0 / rate
    sent = 0
    pending = b""
    next_send = start
    open_ = True
    while open_:
        now = time.monotonic()
        if now - start > duration:
            break
        if now >= next_send:
            t, tx, ty, tz, bx, by, bz = pose_at(poses, poses[0][0] + now - start)
            direction = [bx - tx, by - ty, bz - tz]
            norm = math.sqrt(sum(d * d for d in direction)) or 1.0
            rotation = rotation_from_z([d / norm for d in direction])
            content = transform_content([1000.0 * tx, 1000.0 * ty, 1000.0 * tz], rotation)
            metadata = [("MEMLNodeName", "LinearTransform")]
            pending += pack_message("TRANSFORM", device, timestamp_of(time.time()), content,
                                    version, sent + 1, metadata)
            sent += 1
            next_send += period
        if pending:
            try:
                written = connection.send(pending)
                pending = pending[written:]
            except BlockingIOError:
                pass
        ready, _, _ = select.select([connection], [], [], max(0.0, next_send - time.monotonic()))
        if ready:
            try:
                chunk = connection.recv(1 << 20)
            except BlockingIOError:
                chunk = b"x"
            if not chunk:
                open_ = False
            elif chunk != b"x":
                buffer += chunk
        while len(buffer) >= HEADER_SIZE:
            body_size = struct.unpack(">Q", buffer[42:50])[0]
            if len(buffer) < HEADER_SIZE + body_size:
                break
            # Checked after the session: checking in Python as they come would slow the
            # device below its rate.
            received.append((buffer[:HEADER_SIZE], buffer[HEADER_SIZE:HEADER_SIZE + body_size]))
            buffer = buffer[HEADER_SIZE + body_size:]
    connection.close()
    for header, body in received:
        checks.message(header, body)
    return {
        "header_version": version,
        "poses_sent": sent,
        "received": checks.counts,
        "forces": checks.forces,
        "largest_force_n": checks.largest_force,
        "surfaces": checks.surfaces,
        "closed_surfaces": checks.closed_surfaces,
        "largest_edge_use": checks.largest_edge_use,
        "cut_share_max": checks.cut_share_max,
        "statuses": checks.statuses[:10],
        "failures": checks.failures,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("path")
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--header-version", type=int, choices=(1, 2), default=2)
    parser.add_argument("--rate", type=float, default=500.0)
    parser.add_argument("--hold", type=float, default=0.5)
    arguments = parser.parse_args()
    summary = run(arguments.path, arguments.port, arguments.header_version, arguments.rate,
                  arguments.hold, arguments.host)
    print(json.dumps(summary, indent=2))
    return 1 if summary["failures"] else 0


if __name__ == "__main__":
    sys.exit(main())
