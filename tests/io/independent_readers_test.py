#!/usr/bin/env python3
"""The files incise writes, read by readers incise did not write: VTK's own XML readers
(Debian's python3-vtk9, what ParaView uses) and meshio (Debian's python3-meshio). Every
kind of VTK XML file incise writes (a converted mesh, a subdivision cut, an XFEM cut with its
virtual elements, an XFEM visual surface, a simulation frame) is read by both; the counts must
match incise's own report and the two readers must agree on every array, value for value.

Usage: independent_readers_test.py INCISE SOURCE_DIR DATA_DIR
"""
import json
import subprocess
import sys
import tempfile
from pathlib import Path

try:
    import meshio
    import numpy as np
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy
except ImportError as error:  # scripts/install-deps.sh installs them
    sys.exit(f"FAIL: {error} (python3-meshio, python3-vtk9 and python3-numpy are needed)")

failures = []


def check(condition, message):
    if not condition:
        failures.append(message)
        print("FAIL:", message)


def run(incise, *args):
    result = subprocess.run([incise, *map(str, args)], capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"FAIL: incise {' '.join(map(str, args))}: {result.stderr}")
    return result


def vtk_read(path):
    reader = vtk.vtkXMLUnstructuredGridReader() if path.suffix == ".vtu" else vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    check(reader.GetErrorCode() == 0, f"{path.name}: VTK's reader reports error {reader.GetErrorCode()}")
    return reader.GetOutput()


def integrated_volume(data):
    """What ParaView's Integrate Variables reports as the volume."""
    integrate = vtk.vtkIntegrateAttributes()
    integrate.SetInputData(data)
    integrate.Update()
    return integrate.GetOutput().GetCellData().GetArray("Volume").GetValue(0)


def arrays(data):
    out = {}
    for k in range(data.GetNumberOfArrays()):
        array = data.GetArray(k)
        out[array.GetName()] = vtk_to_numpy(array)
    return out


def compare(path, expected_cells=None):
    """Reads `path` with VTK's reader and (for .vtu: meshio has no .vtp reader) meshio, which
    must agree on points, cells and every array."""
    grid = vtk_read(path)
    points = vtk_to_numpy(grid.GetPoints().GetData())
    cells = grid.GetNumberOfCells()
    check(cells > 0 and grid.GetNumberOfPoints() > 0, f"{path.name}: VTK reads nothing")
    if expected_cells is not None:
        check(cells == expected_cells, f"{path.name}: {cells} cells, incise reported {expected_cells}")
    if grid.IsA("vtkUnstructuredGrid") and cells > 0:
        # Every point is some cell's (unused ones would stretch every point array's range).
        used = np.unique(vtk_to_numpy(grid.GetCells().GetConnectivityArray()))
        check(len(used) == grid.GetNumberOfPoints(),
              f"{path.name}: {grid.GetNumberOfPoints() - len(used)} points no cell uses")
    if path.suffix == ".vtu":
        mesh = meshio.read(path)
        check(np.array_equal(points, mesh.points), f"{path.name}: points differ between VTK and meshio")
        meshio_cells = sum(len(block.data) for block in mesh.cells)
        check(cells == meshio_cells, f"{path.name}: {cells} cells by VTK, {meshio_cells} by meshio")
        check(all(block.type == "tetra" for block in mesh.cells),
              f"{path.name}: meshio reads cells of types {[b.type for b in mesh.cells]}")
        for kind, vtk_arrays, meshio_arrays in (
            ("point", arrays(grid.GetPointData()), mesh.point_data),
            ("cell", arrays(grid.GetCellData()), {k: v[0] for k, v in mesh.cell_data.items()}),
        ):
            check(set(vtk_arrays) == set(meshio_arrays),
                  f"{path.name}: {kind} arrays {sorted(vtk_arrays)} by VTK, {sorted(meshio_arrays)} by meshio")
            for name, values in vtk_arrays.items():
                if name in meshio_arrays:
                    other = np.asarray(meshio_arrays[name]).reshape(values.shape)
                    check(np.array_equal(values, other), f"{path.name}: {kind} array '{name}' differs")
    print(f"{path.name}: {grid.GetNumberOfPoints()} points, {cells} cells, "
          f"point arrays {sorted(arrays(grid.GetPointData()))}, cell arrays {sorted(arrays(grid.GetCellData()))}")
    return grid


def length_unit(data):
    """m per coordinate unit from the file's LengthUnitInMetres field data (None: not said)."""
    array = data.GetFieldData().GetArray("LengthUnitInMetres")
    return None if array is None else array.GetValue(0)


def main():
    incise, source, data = sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3])
    liver = data / "sofa" / "liver.msh"
    if not liver.exists():
        print("SKIP: no data meshes")
        return 0
    work = Path(tempfile.mkdtemp(prefix="incise-readers-"))
    # The liver cut of issue 11 (a vertical blade at 0.513 of its y-extent).
    blade = work / "blade.csv"
    y = 0.217888 + 0.513 * (5.15717 - 0.217888)
    rows = ["t,tip_x,tip_y,tip_z,base_x,base_y,base_z"]
    for i in range(25):
        x = -5.17928 + (1.80331 + 4.67928 + 1.0) * i / 24.0
        rows.append(f"{0.04 * i},{x},{y},-2.2,{x},{y},3.3")
    blade.write_text("\n".join(rows) + "\n")

    run(incise, "convert", liver, work / "liver.vtu")
    info = json.loads(subprocess.run([incise, "info", "--json", liver], capture_output=True, text=True).stdout)
    compare(work / "liver.vtu", info["tets"])

    run(incise, "cut", liver, "--blade", blade, "-o", work / "sub.vtu", "--report", work / "sub.json")
    sub_report = json.loads((work / "sub.json").read_text())
    cut_tets = sub_report["tets_out"]
    # liver.msh does not say its unit (it is centimetres): nothing may claim one.
    check(length_unit(compare(work / "sub.vtu", cut_tets)) is None,
          "sub.vtu claims a length unit the mesh never gave")
    check(sub_report.get("length_unit") == "mesh units",
          f"the cut report says length_unit {sub_report.get('length_unit')!r}, not 'mesh units'")

    # Gmsh and MEDIT files of the cut mesh, read by meshio: every tetrahedron, every point.
    for suffix in (".msh", ".mesh"):
        out = work / ("sub" + suffix)
        run(incise, "convert", work / "sub.vtu", out)
        mesh = meshio.read(out)
        tets = sum(len(block.data) for block in mesh.cells if block.type == "tetra")
        check(tets == cut_tets, f"{out.name}: meshio reads {tets} tetrahedra, incise wrote {cut_tets}")
        used = np.unique(np.concatenate([b.data.ravel() for b in mesh.cells if b.type == "tetra"]))
        check(len(used) == len(mesh.points), f"{out.name}: {len(mesh.points) - len(used)} points no tetrahedron uses")
        # The cut's faces (its lips, back to back) are marked: Gmsh's physical group "cut",
        # MEDIT's reference 1 (the rest of the boundary 0).
        triangles = [i for i, b in enumerate(mesh.cells) if b.type == "triangle"]
        if suffix == ".msh":
            check("cut" in mesh.field_data and len(triangles) == 1,
                  f"{out.name}: no physical group 'cut' of triangles (field data {mesh.field_data})")
            lips = sum(len(mesh.cells[i].data) for i in triangles)
        else:
            refs = np.concatenate([mesh.cell_data["medit:ref"][i] for i in triangles])
            lips = int(np.count_nonzero(refs == 1))
        check(lips > 0 and lips % 2 == 0, f"{out.name}: {lips} cut faces marked (the lips come in pairs)")
        print(f"{out.name}: {len(mesh.points)} points, {tets} tetrahedra, {lips} cut faces (meshio)")

    # The case meshio misread before (raw appended data): XFEM's virtual elements.
    run(incise, "cut", liver, "--blade", blade, "--method", "xfem", "-o", work / "xfem.vtu",
        "--visual", data / "sofa" / "liver-smooth.obj", "--visual-out", work / "xfem.vtp",
        "--report", work / "xfem.json", "--unit", "cm")
    report = json.loads((work / "xfem.json").read_text())
    # Told the unit (cm), every file and the report say it; nothing says metres.
    for name, grid in (("xfem.vtu", compare(work / "xfem.vtu", report["tets_out"])),
                       ("xfem.vtp", compare(work / "xfem.vtp")),
                       ("xfem_clipped.vtu", vtk_read(work / "xfem_clipped.vtu"))):
        check(length_unit(grid) == 0.01, f"{name}: LengthUnitInMetres {length_unit(grid)}, not 0.01")
    check(report.get("length_unit") == "cm" and "blade_travel_m" not in report,
          f"the xfem report's units: length_unit {report.get('length_unit')!r}, keys {sorted(report)}")
    check(abs(report["dofs_added_per_cm"] - report["dofs_added"] / report["blade_travel"]) < 1e-9 * report["dofs_added_per_cm"],
          "dofs_added_per_cm is not the DOFs per centimetre of blade travel")
    # Beside it, the virtual elements clipped to their sides: ParaView's Integrate Variables
    # (vtkIntegrateAttributes) gives the liver's true volume, not the overlapping elements'.
    clipped = compare(work / "xfem_clipped.vtu", report["clipped_tets"])
    true_volume = report["volume_in"]
    check(abs(integrated_volume(clipped) - true_volume) < 1e-9 * true_volume,
          f"xfem_clipped.vtu integrates to {integrated_volume(clipped)}, the liver is {true_volume}")
    overlapping = integrated_volume(vtk_read(work / "xfem.vtu"))
    check(overlapping > 1.05 * true_volume,
          f"the virtual elements themselves integrate to {overlapping} (they overlap by design)")

    # A simulation's frames (an XFEM scene, a few frames).
    frames = work / "frames"
    run(incise, "run", source / "scenes" / "xfem_cut_pull.json", "--frames", 3, "--out", frames)
    written = sorted(frames.glob("*.vtu"))
    check(len(written) > 0, "incise run wrote no .vtu frame")
    for frame in written[:2]:
        compare(frame)
    # Each frame holds its time (VTK's TimeValue field data, what ParaView shows for a single
    # file), the one the .pvd lists, written without float noise (0.03, not 0.030000000000000002).
    import xml.etree.ElementTree as ElementTree
    listed = {Path(d.get("file")).name: d.get("timestep")
              for d in ElementTree.parse(frames / "xfem_cut_pull.pvd").getroot().iter("DataSet")}
    for frame in written[:2]:
        data = vtk_read(frame)
        time = data.GetFieldData().GetArray("TimeValue")
        check(time is not None, f"{frame.name}: no TimeValue field data")
        if time is not None and frame.name in listed:
            check(abs(time.GetValue(0) - float(listed[frame.name])) < 1e-12,
                  f"{frame.name}: TimeValue {time.GetValue(0)}, the .pvd says {listed[frame.name]}")
        check(length_unit(data) == 1.0, f"{frame.name}: a scene's frame is not said to be in metres")
    check("point coordinates in m," in (frames / "xfem_cut_pull.pvd").read_text(),
          "the .pvd does not say its unit")
    for name, timestep in listed.items():
        check(len(timestep) <= 14, f"{name}: timestep '{timestep}' carries float noise")
    # ParaView's series reader offers the arrays of the first frame: `fraction` is there.
    first = vtk_read(frames / "xfem_cut_pull_000000.vtu")
    check(first.GetCellData().GetArray("fraction") is not None,
          "the first frame of an XFEM scene has no 'fraction' array")
    clipped_frames = sorted(frames.glob("xfem_cut_pull_clipped_*.vtu"))
    check(len(clipped_frames) == len(written) - len(clipped_frames) and (frames / "xfem_cut_pull_clipped.pvd").exists(),
          "no clipped series beside the frames")
    if clipped_frames:
        at_rest = integrated_volume(compare(clipped_frames[0]))
        volume = integrated_volume(first)
        check(abs(at_rest - volume) < 1e-9 * volume,
              f"the first clipped frame integrates to {at_rest}, the body is {volume}")

    if failures:
        print(f"{len(failures)} failures")
        return 1
    print("every file read alike by VTK and meshio")
    return 0


if __name__ == "__main__":
    sys.exit(main())
