#!/usr/bin/env python3
"""A synthetic head CT at clinical size, for planning benchmarks and tests: skin, a fat layer,
muscle-like soft tissue, a skull shell, a maxilla joined to the skull, a separate mandible and
a cervical vertebra, with partial-volume ramps at every interface and scanner-like noise.

Values are CT numbers stored as unsigned 16-bit with the usual +1024 offset (air 0, fat 924,
soft tissue 1064, bone 2200), so a plan's iso values are the examples' (skin 500, bone 1600).
Patient frame (mm): x to the patient's left, y to the back (the face looks toward -y), z to
the crown; the volume's origin is its first voxel centre.

usage: bench/head_phantom.py OUT_DIR [--size 512 512 300] [--spacing 0.5 0.5 0.8]
                             [--noise 15] [--seed 1] [--dicom] [--surfaces]

Writes OUT_DIR/head.mhd (+ head.raw) and, with --dicom, a CT series OUT_DIR/dicom/slice_NNNN.dcm
(pydicom, Debian's python3-pydicom). The plan of the issue's benchmark is written beside it as
OUT_DIR/plan.json: skin 500, bone 1600, three layers, a Le Fort I-like osteotomy through the
maxilla and the maxilla advanced 5 mm along its own cut; with --dicom also
OUT_DIR/plan_dicom.json, the same plan on the series, its iso values in Hounsfield units.
With --surfaces, the skin and bone as a segmentation tool exports them (VTK's flying edges at
the plan's iso values, the largest connected piece, unsmoothed: OUT_DIR/skin.stl, bone.stl;
python3-vtk9) and OUT_DIR/plan_surfaces.json, the same plan on those files.
"""
import argparse
import json
import os

import numpy as np

AIR, FAT, SOFT, BONE = 0.0, 924.0, 1064.0, 2200.0

# Anatomy (mm). The head: an ellipsoid; the neck: an elliptic cylinder below it.
HEAD_CENTRE = np.array([0.0, 0.0, 10.0])
HEAD_AXES = np.array([72.0, 92.0, 100.0])
NECK_AXES = np.array([52.0, 56.0])
NECK_TOP = -40.0
SKIN = 2.0  # mm
FAT_DEPTH = 7.0  # mm below the surface, fat from SKIN to FAT_DEPTH
SKULL_OUTER = 9.0  # mm below the surface of the head
SKULL_INNER = 15.0
SKULL_BOTTOM = -25.0  # z of the skull's base (the maxilla joins below it in front)
LE_FORT_Z = -38.0  # the example osteotomy plane


def ellipsoid_depth(p, centre, axes):
    """Approximate signed depth below an ellipsoid's surface (mm, positive inside)."""
    q = (p - centre) / axes
    r = np.sqrt(np.sum(q * q, axis=-1))
    return (1.0 - r) * axes.min()


def ramp(depth, width):
    """0 outside, 1 inside, linear across one voxel: a partial volume."""
    return np.clip(depth / width + 0.5, 0.0, 1.0)


def waves(rng, count, shortest, longest, amplitude):
    """A smooth random field: a sum of plane waves (mm), as a function of (x, y, z)."""
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    numbers = 2.0 * np.pi / rng.uniform(shortest, longest, count)
    phases = rng.uniform(0.0, 2.0 * np.pi, count)
    scale = amplitude / np.sqrt(count / 2.0)

    def field(x, y, z):
        total = 0.0
        for d, k, phase in zip(directions, numbers, phases):
            total = total + np.sin(k * (d[0] * x + d[1] * y + d[2] * z) + phase)
        return scale * total

    return field


def phantom(size, spacing, noise, seed):
    nx, ny, nz = size
    extent = np.array(size, dtype=float) * np.array(spacing)
    origin = np.array([-extent[0] / 2, -extent[1] / 2 + 10.0, 115.0 - extent[2]])
    width = float(max(spacing))
    volume = np.empty((nz, ny, nx), dtype=np.uint16)
    rng = np.random.default_rng(seed)
    # Skin relief (wrinkles, the face's small features), the skull's varying thickness and
    # cancellous bone whose density dips below the bone iso value in places, as real scans do.
    relief = waves(rng, 12, 10.0, 40.0, 1.0)
    thickness = waves(rng, 8, 20.0, 60.0, 1.5)
    cancellous = waves(rng, 16, 3.0, 8.0, 1.0)
    x = origin[0] + spacing[0] * np.arange(nx)
    y = origin[1] + spacing[1] * np.arange(ny)
    xx, yy = np.meshgrid(x, y, indexing="xy")  # (ny, nx)
    for k in range(nz):
        z = origin[2] + spacing[2] * k
        p = np.stack([xx, yy, np.full_like(xx, z)], axis=-1)
        head = ellipsoid_depth(p, HEAD_CENTRE, HEAD_AXES)
        neck = (1.0 - np.sqrt((xx / NECK_AXES[0]) ** 2 + ((yy - 8.0) / NECK_AXES[1]) ** 2)) \
            * NECK_AXES.min()
        if z > NECK_TOP:
            neck = np.minimum(neck, (NECK_TOP + 30.0 - z) * 0.8)
        nose = ellipsoid_depth(p, np.array([0.0, -88.0, -5.0]), np.array([11.0, 16.0, 24.0]))
        # Ears: thin flaps on the sides.
        ears = np.maximum(
            ellipsoid_depth(p, np.array([-74.0, 5.0, 0.0]), np.array([5.0, 16.0, 28.0])),
            ellipsoid_depth(p, np.array([74.0, 5.0, 0.0]), np.array([5.0, 16.0, 28.0])))
        body = np.maximum(np.maximum(head, neck), np.maximum(nose, ears)) + relief(xx, yy, z)
        # An airway: air inside the neck, closed (the mouth shut).
        airway = np.minimum(7.0 - np.hypot(xx, yy + 8.0), np.minimum(z + 125.0, -45.0 - z))
        body = np.minimum(body, -airway)
        value = SOFT * ramp(body, width)
        # Fat between the skin and the muscle: lower density under the skin.
        value -= (SOFT - FAT) * ramp(body - SKIN, width) * ramp(FAT_DEPTH - body, width)
        # Skull: a shell under the scalp, above its base.
        skull = np.minimum(head - SKULL_OUTER, SKULL_INNER + thickness(xx, yy, z) - head)
        skull = np.minimum(skull, z - SKULL_BOTTOM)
        # Maxilla: a block under the front of the skull, joined to it, down to the teeth.
        maxilla = np.minimum(np.minimum(28.0 - np.abs(xx), np.minimum(-52.0 - yy, yy + 80.0)),
                             min(z - (LE_FORT_Z - 14.0), SKULL_BOTTOM + 4.0 - z))
        # Mandible: a horseshoe bar under the maxilla, rami up the back (a gap to the skull).
        t = np.clip(np.arctan2(-(yy + 10.0) / 70.0, xx / 48.0), 0.0, np.pi)
        arc = np.stack([48.0 * np.cos(t), -10.0 - 70.0 * np.sin(t)], axis=-1)
        bar = 7.0 - np.hypot(xx - arc[..., 0], yy - arc[..., 1])
        mandible = np.minimum(bar, np.minimum(z + 80.0, LE_FORT_Z - 18.0 - z))
        ramus = np.minimum(7.0 - np.hypot(np.abs(xx) - 48.0, yy + 10.0),
                           np.minimum(z + 80.0, SKULL_BOTTOM - 6.0 - z))
        mandible = np.maximum(mandible, ramus)
        # A cervical vertebra: a cylinder behind the airway.
        vertebra = np.minimum(11.0 - np.hypot(xx, yy - 20.0), np.minimum(z + 125.0, -60.0 - z))
        bone = np.maximum(np.maximum(skull, maxilla), np.maximum(mandible, vertebra))
        bone_value = BONE - 250.0 + 450.0 * cancellous(xx, yy, z) * ramp(bone - 2.0, width)
        # A sinus: air inside the maxilla.
        sinus = ellipsoid_depth(p, np.array([0.0, -66.0, -30.0]), np.array([16.0, 8.0, 6.0]))
        value += (bone_value - SOFT) * ramp(bone, width)
        value -= value * ramp(sinus, width)
        # The scanner's table: a curved plate behind the head, a separate body.
        table = np.minimum(4.0 - np.abs(yy - 100.0 - 0.004 * xx * xx), 110.0 - np.abs(xx))
        value += 1200.0 * ramp(table, width)
        value += rng.normal(0.0, noise, value.shape) * (value > 0.5 * FAT)
        volume[k] = np.clip(np.rint(value), 0, 65535).astype(np.uint16)
    return volume, origin


def write_metaimage(out_dir, volume, origin, spacing):
    nz, ny, nx = volume.shape
    volume.astype("<u2").tofile(os.path.join(out_dir, "head.raw"))
    with open(os.path.join(out_dir, "head.mhd"), "w") as f:
        f.write("ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
                f"Offset = {origin[0]} {origin[1]} {origin[2]}\n"
                "TransformMatrix = 1 0 0 0 1 0 0 0 1\n"
                f"ElementSpacing = {spacing[0]} {spacing[1]} {spacing[2]}\n"
                f"DimSize = {nx} {ny} {nz}\nElementType = MET_USHORT\nElementDataFile = head.raw\n")


def write_dicom(out_dir, volume, origin, spacing):
    from pydicom.dataset import FileDataset, FileMetaDataset
    from pydicom.uid import CTImageStorage, ExplicitVRLittleEndian, generate_uid

    series = generate_uid()
    study = generate_uid()
    frame = generate_uid()
    folder = os.path.join(out_dir, "dicom")
    os.makedirs(folder, exist_ok=True)
    nz, ny, nx = volume.shape
    for k in range(nz):
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID = CTImageStorage
        meta.MediaStorageSOPInstanceUID = generate_uid()
        meta.TransferSyntaxUID = ExplicitVRLittleEndian
        path = os.path.join(folder, f"slice_{k:04d}.dcm")
        ds = FileDataset(path, {}, file_meta=meta, preamble=b"\0" * 128)
        ds.SOPClassUID = CTImageStorage
        ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
        ds.Modality = "CT"
        ds.PatientName = "Phantom^Head"
        ds.PatientID = "incise-phantom"
        ds.StudyInstanceUID = study
        ds.SeriesInstanceUID = series
        ds.FrameOfReferenceUID = frame
        ds.SeriesNumber = 1
        ds.InstanceNumber = k + 1
        ds.ImagePositionPatient = [f"{origin[0]:.4f}", f"{origin[1]:.4f}",
                                   f"{origin[2] + k * spacing[2]:.4f}"]
        ds.ImageOrientationPatient = [1, 0, 0, 0, 1, 0]
        ds.PixelSpacing = [spacing[1], spacing[0]]  # row spacing (y), column spacing (x)
        ds.SliceThickness = spacing[2]
        ds.Rows, ds.Columns = ny, nx
        ds.SamplesPerPixel = 1
        ds.PhotometricInterpretation = "MONOCHROME2"
        ds.BitsAllocated = 16
        ds.BitsStored = 16
        ds.HighBit = 15
        ds.PixelRepresentation = 0
        ds.RescaleIntercept = -1024
        ds.RescaleSlope = 1
        ds.PixelData = volume[k].astype("<u2").tobytes()
        ds.is_little_endian = True
        ds.is_implicit_VR = False
        ds.save_as(path, write_like_original=False)


def write_plan(out_dir, image_name, plan_name="plan.json", offset=0):
    """The benchmark's plan; `offset` is added to the iso values (the DICOM series stores the
    same numbers with RescaleIntercept -1024, so a reader gives Hounsfield units: -1024)."""
    plan = {
        "description": "incise's synthetic head CT (bench/head_phantom.py): skin at 500, bone at "
                       "1600, three layers, a Le Fort I-like osteotomy through the maxilla and "
                       "the maxilla advanced 5 mm along its own cut (toward the face, -y).",
        "image": image_name,
        "iso": {"skin": 500 + offset, "bone": 1600 + offset},
        "layers": 3,
        "decimation": {"max_error": 0.5},
        "materials": {"young_modulus": 15000, "density": 1050},
        "skin_prestrain": 0.05,
        "volume_weight": 30000,
        "gravity": [0, 9.81, 0],
        "max_thickness": 15,
        "osteotomies": [{"point": [0, -66, LE_FORT_Z], "normal": [0, 0, 1], "radius": 60}],
        "moves": [{"segment_near": [0, -80, LE_FORT_Z - 8], "translate": [0, -5, 0]}],
        "method": "energy",
        "solver": {"type": "newton"},
    }
    if offset:
        plan["description"] += f" Iso values in Hounsfield units (the stored numbers {offset:+d})."
    with open(os.path.join(out_dir, plan_name), "w") as f:
        json.dump(plan, f, indent=2)


def write_surfaces(out_dir):
    """Skin and bone as surface files and the plan on them (a surface-file plan's benchmark)."""
    import vtk  # python3-vtk9, only for this option

    reader = vtk.vtkMetaImageReader()
    reader.SetFileName(os.path.join(out_dir, "head.mhd"))
    for iso, name in ((500, "skin"), (1600, "bone")):
        edges = vtk.vtkFlyingEdges3D()
        edges.SetInputConnection(reader.GetOutputPort())
        edges.SetValue(0, iso)
        largest = vtk.vtkPolyDataConnectivityFilter()
        largest.SetInputConnection(edges.GetOutputPort())
        largest.SetExtractionModeToLargestRegion()
        writer = vtk.vtkSTLWriter()
        writer.SetInputConnection(largest.GetOutputPort())
        writer.SetFileName(os.path.join(out_dir, f"{name}.stl"))
        writer.SetFileTypeToBinary()
        writer.Write()
    with open(os.path.join(out_dir, "plan.json")) as f:
        plan = json.load(f)
    del plan["image"], plan["iso"]
    plan["surfaces"] = {"skin": "skin.stl", "bone": "bone.stl"}
    plan["description"] += " On surface files (VTK flying edges, unsmoothed), decimated to 0.5 mm."
    with open(os.path.join(out_dir, "plan_surfaces.json"), "w") as f:
        json.dump(plan, f, indent=2)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("out_dir")
    parser.add_argument("--size", type=int, nargs=3, default=[512, 512, 300])
    parser.add_argument("--spacing", type=float, nargs=3, default=[0.5, 0.5, 0.8])
    parser.add_argument("--noise", type=float, default=15.0, help="CT numbers, standard deviation")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--dicom", action="store_true", help="also write a DICOM series")
    parser.add_argument("--surfaces", action="store_true",
                        help="also write skin.stl and bone.stl and a plan on them")
    args = parser.parse_args()
    os.makedirs(args.out_dir, exist_ok=True)
    volume, origin = phantom(args.size, args.spacing, args.noise, args.seed)
    write_metaimage(args.out_dir, volume, origin, args.spacing)
    if args.dicom:
        write_dicom(args.out_dir, volume, origin, args.spacing)
    write_plan(args.out_dir, "head.mhd")
    if args.dicom:
        write_plan(args.out_dir, "dicom", "plan_dicom.json", -1024)
    if args.surfaces:
        write_surfaces(args.out_dir)
    print(f"{args.out_dir}/head.mhd: {args.size[0]} x {args.size[1]} x {args.size[2]} voxels of "
          f"{args.spacing[0]} x {args.spacing[1]} x {args.spacing[2]} mm")


if __name__ == "__main__":
    main()
