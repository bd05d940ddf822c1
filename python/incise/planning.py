"""Surgical planning from Python: ``incise.plan``."""

import json
import os
import tempfile

from ._incise import _run_plan, read_surface


def plan(plan, out_dir=None, plan_file=None, progress=None):
    """Runs a surgical plan (Teschner et al.): bone and skin from a CT, the tissue between them,
    the osteotomies and bone moves, and the face predicted by energy minimisation.

    plan: a plan file's path or a dict with the same keys (docs: the README's planning section).
    out_dir: where the files go (skin_before/after.vtp, bone_before/after.vtp, tissue.vtu,
    report.json); a new temporary folder by default. plan_file: for a dict, the file it stands
    for (errors name it; relative paths such as the CT resolve against its folder).
    progress: called as progress(stage, fraction) while it runs.

    Returns a dict: the summary (points, springs, prisms, segments, residual forces in N,
    max_displacement_mm, seconds), ``report`` (report.json as a dict), ``skin_triangles`` (k, 3),
    ``skin_before`` / ``skin_after`` (n, 3) in m, ``bone_before`` / ``bone_after`` as
    (points, triangles), and ``out_dir``. The GIL is released while it runs."""
    if out_dir is None:
        out_dir = tempfile.mkdtemp(prefix="incise-plan-")
    if not isinstance(plan, dict):
        plan = os.fspath(plan)
    result = _run_plan(plan, plan_file, os.fspath(out_dir), progress)
    with open(result["report_path"], encoding="utf-8") as report:
        result["report"] = json.load(report)
    for name in ("bone_before", "bone_after"):
        path = os.path.join(out_dir, name + ".vtp")
        result[name] = read_surface(path) if os.path.exists(path) else None
    result["out_dir"] = str(out_dir)
    return result
