#!/usr/bin/env python3
"""incise plan --view driven by real mouse and key events (xdotool in a virtual X server).

The other planning-window tests play recorded requests; this one moves the pointer and presses
the buttons as a surgeon would, so what it checks is the window's own handling of the mouse:
  1. the bone view (B), the skull's cap (segment 0, selected) dragged up: one nudge straight up
     the screen (+z, mm), predicted;
  2. the cap turned with Shift+drag: one nudge about the axis towards the camera (y), predicted;
  3. the cap dragged far down into the rest of the skull: it stops at contact;
  4. S saves, Esc closes.
Then: the recording holds the three nudges; the saved plan moves the cap up, turned, and
incise plan runs it (it refuses segments that interpenetrate) to the prediction the window
showed; the recording replays to that prediction bit for bit.
A second session starts from a plan without osteotomies: O shows a plane, it follows the bone
under the pointer, a click cuts there; the saved plan has that plane and makes two segments.

Usage: plan_view_mouse_test.py INCISE          (starts its own X server with xvfb-run)
Exit 77 (skipped) without xvfb-run or xdotool, unless INCISE_REQUIRE_GL is set.
"""
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

WIDTH, HEIGHT = 1000, 800
TIMEOUT_S = 120.0


def write_sphere_obj(path, radius_mm, rings=24):
    """A UV sphere about the origin (mm), outward-facing triangles."""
    points = [(0.0, 0.0, radius_mm)]
    around = 2 * rings
    for i in range(1, rings):
        theta = math.pi * i / rings
        for j in range(around):
            phi = 2 * math.pi * j / around
            points.append((radius_mm * math.sin(theta) * math.cos(phi),
                           radius_mm * math.sin(theta) * math.sin(phi),
                           radius_mm * math.cos(theta)))
    points.append((0.0, 0.0, -radius_mm))
    triangles = [(0, 1 + j, 1 + (j + 1) % around) for j in range(around)]
    for i in range(rings - 2):
        for j in range(around):
            a = 1 + i * around + j
            b = 1 + i * around + (j + 1) % around
            triangles += [(a, a + around, b), (b, a + around, b + around)]
    last = len(points) - 1
    base = 1 + (rings - 2) * around
    triangles += [(base + j, last, base + (j + 1) % around) for j in range(around)]
    with open(path, "w") as out:
        out.writelines("v %r %r %r\n" % p for p in points)
        out.writelines("f %d %d %d\n" % (a + 1, b + 1, c + 1) for a, b, c in triangles)


def xdotool(*arguments):
    subprocess.run(["xdotool", *[str(a) for a in arguments]], check=True)


def wait_for(what, holds):
    deadline = time.monotonic() + TIMEOUT_S
    while not holds():
        if time.monotonic() > deadline:
            raise AssertionError("timed out waiting for " + what)
        time.sleep(0.05)


def drag(points, shift=False):
    """Press on the first point, move through the others, release at the last."""
    if shift:
        xdotool("keydown", "shift")
    xdotool("mousemove", *points[0])
    time.sleep(0.3)
    xdotool("mousedown", 1)
    time.sleep(0.3)  # the press is seen in a frame of its own
    for point in points[1:]:
        xdotool("mousemove", *point)
        time.sleep(0.05)
    time.sleep(0.3)
    xdotool("mouseup", 1)
    if shift:
        xdotool("keyup", "shift")


# Where the bone's cap is drawn: the camera looks from the front (-y), z up the screen; the
# bone sphere (40 mm) is drawn about the window's centre, its cap (above z = 20 mm) at the top,
# right of the panel.
CAP = (WIDTH // 2 + 60, HEIGHT * 29 // 100)


def open_window(incise, work, plan, name):
    """incise plan PLAN --view, its console into NAME.out; the process and a reader of that."""
    log = open(os.path.join(work, name + ".out"), "w")
    window = subprocess.Popen(
        [incise, "plan", plan, "--view", "--size", "%dx%d" % (WIDTH, HEIGHT),
         "--record", name + "_recorded.json", "--save", name + "_saved.json"],
        cwd=work, stdout=log, stderr=subprocess.STDOUT)

    def printed():
        with open(os.path.join(work, name + ".out")) as f:
            return f.read()

    def prediction(n):
        wait_for("prediction %d" % n,
                 lambda: "prediction %d:" % n in printed() or window.poll() is not None)
        assert window.poll() is None, printed()
        time.sleep(0.5)  # the worker is idle again a moment after it has printed

    return window, printed, prediction


def save_and_close(work, name, window, printed):
    xdotool("key", "s")
    wait_for("the plan saved", lambda: os.path.exists(os.path.join(work, name + "_saved.json")))
    time.sleep(0.5)
    xdotool("key", "Escape")
    assert window.wait(timeout=TIMEOUT_S) == 0, printed()


def inner(incise, work):
    """In the X server: the sessions by mouse and keys."""
    move_by_mouse(incise, work)
    cut_by_mouse(incise, work)
    return 0


def cut_by_mouse(incise, work):
    window, printed, prediction = open_window(incise, work, "uncut.json", "cut")
    try:
        prediction(1)
        xdotool("key", "o")  # the bone view, a plane through the bone under the pointer
        time.sleep(0.3)
        xdotool("mousemove", CAP[0], CAP[1] + 10)
        time.sleep(0.5)
        xdotool("click", 1)
        prediction(2)
        save_and_close(work, "cut", window, printed)
    finally:
        if window.poll() is None:
            window.kill()


def move_by_mouse(incise, work):
    window, printed, prediction = open_window(incise, work, "plan.json", "move")

    try:
        prediction(1)
        xdotool("key", "b")
        time.sleep(0.3)
        cx, cy = CAP
        drag([(cx, cy)] + [(cx, cy - d) for d in range(5, 35, 5)])  # 30 pixels up
        prediction(2)
        # Shift+drag from the right of the cap's centre to its upper left: counter-clockwise.
        drag([(cx + 60, cy)] + [(cx + 60 - d, cy - d // 3) for d in range(10, 50, 10)],
             shift=True)
        prediction(3)
        # Far down, through the rest of the skull: the cap stops at contact.
        drag([(cx, cy - 20)] + [(cx, cy - 20 + d) for d in range(20, 220, 20)])
        save_and_close(work, "move", window, printed)
    finally:
        if window.poll() is None:
            window.kill()


def summary_displacement(text):
    at = text.rindex("largest skin displacement ")
    return float(text[at + len("largest skin displacement "):].split()[0])


def main():
    incise = os.path.abspath(sys.argv[1])
    if len(sys.argv) > 3 and sys.argv[2] == "--inner":
        return inner(incise, sys.argv[3])
    missing = [tool for tool in ("xvfb-run", "xdotool") if shutil.which(tool) is None]
    if missing:
        if os.environ.get("INCISE_REQUIRE_GL"):
            print("INCISE_REQUIRE_GL is set and %s is missing (apt-get install xvfb xdotool)"
                  % " and ".join(missing))
            return 1
        print("skipped: no %s here" % " or ".join(missing))
        return 77
    work = tempfile.mkdtemp(prefix="incise_plan_mouse_")
    write_sphere_obj(os.path.join(work, "skin.obj"), 50.0)
    write_sphere_obj(os.path.join(work, "bone.obj"), 40.0)
    with open(os.path.join(work, "plan.json"), "w") as f:
        json.dump({"surfaces": {"skin": "skin.obj", "bone": "bone.obj"}, "layers": 2,
                   "osteotomies": [{"point": [0, 0, 20], "normal": [0, 0, 1]}]}, f)
    with open(os.path.join(work, "uncut.json"), "w") as f:
        json.dump({"surfaces": {"skin": "skin.obj", "bone": "bone.obj"}, "layers": 2}, f)
    x_server = ["xvfb-run", "-a", "-s", "-screen 0 1280x1024x24"]
    session = subprocess.run(x_server + [sys.executable, os.path.abspath(__file__), incise,
                                         "--inner", work])
    with open(os.path.join(work, "move.out")) as f:
        shown = f.read()
    print(shown)
    if os.path.exists(os.path.join(work, "cut.out")):
        with open(os.path.join(work, "cut.out")) as f:
            print(f.read())
    assert session.returncode == 0, "the sessions by mouse failed"

    # The recording: three nudges of the cap, as the mouse made them.
    with open(os.path.join(work, "move_recorded.json")) as f:
        requests = json.load(f)["requests"]
    nudges = [r["nudge"] for r in requests if "nudge" in r]
    assert len(nudges) == 3, requests
    assert all(n["segment"] == 0 for n in nudges), nudges
    up, turn, push = nudges
    # 30 pixels up the screen at about 5 pixels a millimetre: 4-8 mm along +z, nothing else.
    assert 4.0 < up["translate_mm"][2] < 8.0, up
    assert abs(up["translate_mm"][0]) < 0.5 and abs(up["translate_mm"][1]) < 1e-9, up
    assert up["rotate_deg"] == [0.0, 0.0, 0.0], up
    # Counter-clockwise on the screen seen from the front: a turn about -y, a few degrees.
    assert turn["translate_mm"] == [0.0, 0.0, 0.0], turn
    assert -30.0 < turn["rotate_deg"][1] < -1.0, turn
    assert abs(turn["rotate_deg"][0]) < 1e-9 and abs(turn["rotate_deg"][2]) < 1e-9, turn
    assert push["translate_mm"][2] < -2 * up["translate_mm"][2], push
    assert {"save": "move_saved.json"} in requests, requests

    # The saved plan: the cap up (stopped at contact on the way down, so still above where it
    # was) and turned.
    with open(os.path.join(work, "move_saved.json")) as f:
        moves = json.load(f)["moves"]
    assert len(moves) == 1, moves
    assert 0.0 < moves[0]["translate"][2] < up["translate_mm"][2], moves
    assert abs(moves[0]["rotate"]["angle_deg"] - abs(turn["rotate_deg"][1])) < 1e-6, moves
    predictions = shown.count("prediction ")
    assert predictions == 4, "one prediction to start and one per nudge: " + shown

    # incise plan runs the saved plan (it refuses segments that interpenetrate) to the
    # prediction the window showed, within the solver's tolerance.
    out = os.path.join(work, "out")
    run = subprocess.run([incise, "plan", os.path.join(work, "move_saved.json"), "--out", out],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    with open(os.path.join(out, "report.json")) as f:
        report = json.load(f)
    last = summary_displacement(shown)
    assert last > 0.5, shown
    assert abs(report["max_displacement"] - last) < 1e-3, (report["max_displacement"], last)

    # The recording replays to the same prediction, bit for bit.
    replay = subprocess.run(x_server + [incise, "plan", "plan.json", "--view", "--size", "640x480",
                                        "--replay", "move_recorded.json"],
                            cwd=work, capture_output=True, text=True)
    assert replay.returncode == 0, replay.stdout + replay.stderr
    assert summary_displacement(replay.stdout) == last, (replay.stdout, shown)

    # The plane placed by the mouse: through the bone point clicked (on the 40 mm sphere, in
    # its upper half), level on the screen and tipped 30 degrees towards the camera; the saved
    # plan cuts the skull in two.
    with open(os.path.join(work, "cut_saved.json")) as f:
        planes = json.load(f)["osteotomies"]
    assert len(planes) == 1, planes
    point, normal = planes[0]["point"], planes[0]["normal"]
    assert abs(math.sqrt(sum(c * c for c in point)) - 40.0) < 1.0, point
    assert 5.0 < point[2] < 40.0, point
    assert abs(normal[0]) < 1e-6 and abs(abs(normal[1]) - 0.5) < 1e-6, normal
    assert abs(normal[2] - math.sqrt(0.75)) < 1e-6, normal
    cut = subprocess.run([incise, "plan", os.path.join(work, "cut_saved.json"), "--out",
                          os.path.join(work, "cut_out")], capture_output=True, text=True)
    assert cut.returncode == 0, cut.stderr
    with open(os.path.join(work, "cut_out", "report.json")) as f:
        assert json.load(f)["segments"] == 2
    shutil.rmtree(work)
    print("ok: dragged, turned, stopped at contact, saved, run and replayed; a plane placed "
          "and clicked")
    return 0


if __name__ == "__main__":
    sys.exit(main())
