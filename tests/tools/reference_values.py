#!/usr/bin/env python3
"""Independent reference values for the reader tests (tests/io/real_data_test.cpp).

A deliberately separate, minimal parser in plain Python (no incise code): it reads the ASCII
files of ../shared/data and prints vertex count, tetrahedron count and the sum of signed
tetrahedron volumes. Run from the project root: python3 tests/tools/reference_values.py
"""
import re
import sys
from pathlib import Path

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data"


def volume(points, tets):
    total = 0.0
    for a, b, c, d in tets:
        pa, pb, pc, pd = points[a], points[b], points[c], points[d]
        u = [pb[i] - pa[i] for i in range(3)]
        v = [pc[i] - pa[i] for i in range(3)]
        w = [pd[i] - pa[i] for i in range(3)]
        total += (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
                  + u[2] * (v[0] * w[1] - v[1] * w[0])) / 6.0
    return total


def gmsh(path):
    lines = path.read_text().split("\n")
    points, index, tets = [], {}, []
    i = 0
    v1 = lines[0].strip() == "$NOD"
    while i < len(lines):
        line = lines[i].strip()
        if line in ("$NOD", "$Nodes"):
            n = int(lines[i + 1])
            for k in range(n):
                f = lines[i + 2 + k].split()
                index[int(f[0])] = len(points)
                points.append([float(x) for x in f[1:4]])
            i += 2 + n
        elif line in ("$ELM", "$Elements"):
            n = int(lines[i + 1])
            for k in range(n):
                f = [int(x) for x in lines[i + 2 + k].split()]
                if f[1] == 4:
                    nodes = f[5:9] if v1 else f[3 + f[2]:7 + f[2]]
                    tets.append([index[x] for x in nodes])
            i += 2 + n
        else:
            i += 1
    return points, tets


def vtu_ascii(path):
    text = path.read_text()
    def array(name):
        m = re.search(r'<DataArray[^>]*Name="%s"[^>]*>(.*?)</DataArray>' % name, text, re.S)
        return m.group(1).split()
    pts = re.search(r"<Points>\s*<DataArray[^>]*>(.*?)</DataArray>", text, re.S).group(1).split()
    points = [[float(x) for x in pts[i:i + 3]] for i in range(0, len(pts), 3)]
    conn = [int(x) for x in array("connectivity")]
    offs = [int(x) for x in array("offsets")]
    types = [int(x) for x in array("types")]
    tets, start = [], 0
    for end, t in zip(offs, types):
        if t == 10:
            tets.append(conn[start:end])
        start = end
    return points, tets


def tetgen(path):
    def rows(p):
        return [l.split() for l in p.read_text().split("\n") if l.strip() and not l.startswith("#")]
    node = rows(path.with_suffix(".node"))
    base = int(node[1][0])
    points = [[float(x) for x in r[1:4]] for r in node[1:]]
    ele = rows(path.with_suffix(".ele"))
    tets = [[int(x) - base for x in r[1:5]] for r in ele[1:]]
    return points, tets


def medit(path):
    tokens = path.read_text().split()
    points, tets = [], []
    i = 0
    while i < len(tokens):
        key = tokens[i].lower()
        if key == "vertices":
            n = int(tokens[i + 1])
            points = [[float(x) for x in tokens[i + 2 + 4 * k:i + 5 + 4 * k]] for k in range(n)]
            i += 2 + 4 * n
        elif key == "tetrahedra":
            n = int(tokens[i + 1])
            tets = [[int(x) - 1 for x in tokens[i + 2 + 5 * k:i + 6 + 5 * k]] for k in range(n)]
            i += 2 + 5 * n
        else:
            i += 1
    return points, tets


READERS = {".msh": gmsh, ".vtu": vtu_ascii, ".ele": tetgen, ".mesh": medit}

if __name__ == "__main__":
    for name in sys.argv[1:] or [
        "sofa/liver.msh", "sofa/cylinder.msh", "sofa/cube_low_res.msh", "sofa/single_tetra.msh",
        "sofa/6_tetra_bad.msh", "sofa-mor/liverTinyMesh.vtu", "sofa-mor/liverVeryCOARSE.vtu",
        "sofa-mor/liverCoarse.vtu", "sofa-mor/liverSemiFine.vtu", "pbd/armadillo_4k.ele",
        "libigl/octopus-low.mesh"]:
        path = DATA / name
        points, tets = READERS[path.suffix](path)
        print(f"{name}: vertices {len(points)} tets {len(tets)} volume {volume(points, tets)!r}")
