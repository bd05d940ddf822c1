#!/usr/bin/env python3
"""Runs every command of the user guide's ```sh blocks (docs/*.md), in order, page by page, in
a scratch folder that links to the repository's scenes/ and tests/, with ../shared beside it
as in a checkout: each must exit 0. `incise` at the start
of a line is the built program; a line ending in ` &` runs in the background (a server) and
must have exited 0 within two minutes of the page's last command. Every relative link of the
README, the guide and the scene reference must lead to a file, and every example of
docs/examples/ (compiled and run by CTest) must be shown whole on a page.

usage: doc_commands_test.py INCISE SOURCE_DIR
"""
import os
import pathlib
import re
import shlex
import subprocess
import sys
import tempfile


def commands(page):
    """The lines of a page's ```sh blocks, in order."""
    found, inside = [], False
    for line in page.read_text().splitlines():
        if line.startswith("```"):
            inside = line.strip() == "```sh" if not inside else False
            continue
        if inside and line.strip() and not line.lstrip().startswith("#"):
            found.append(line.strip())
    return found


def run_page(incise, source, page):
    """Runs a page's commands in a fresh folder; returns (commands run, failures)."""
    ran, failures = 0, []
    with tempfile.TemporaryDirectory() as root:
        # As in a checkout: the repository's scenes/ and tests/ here, ../shared beside it (the
        # scenes reach the data meshes as ../../shared/data).
        scratch = os.path.join(root, "work")
        os.mkdir(scratch)
        for name in ("scenes", "tests"):
            os.symlink(source / name, os.path.join(scratch, name))
        if (source.parent / "shared").exists():
            os.symlink(source.parent / "shared", os.path.join(root, "shared"))
        background = []
        for command in commands(page):
            in_background = command.endswith(" &")
            words = shlex.split(command[:-2] if in_background else command)
            if words[0] == "incise":
                words[0] = incise
            ran += 1
            if in_background:
                background.append((command, subprocess.Popen(
                    words, cwd=scratch, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                    text=True)))
                continue
            result = subprocess.run(words, cwd=scratch, capture_output=True, text=True,
                                    timeout=600)
            print(f"{page.name}: {command}: exit {result.returncode}", flush=True)
            if result.returncode != 0:
                failures.append(f"{page.name}: {command}\n{result.stdout[-2000:]}\n"
                                f"{result.stderr[-2000:]}")
        for command, process in background:
            try:
                out, err = process.communicate(timeout=120)
            except subprocess.TimeoutExpired:
                process.kill()
                out, err = process.communicate()
            print(f"{page.name}: {command}: exit {process.returncode}", flush=True)
            if process.returncode != 0:
                failures.append(f"{page.name}: {command}\n{out[-2000:]}\n{err[-2000:]}")
    return ran, failures


def broken_links(source):
    """Relative links of the README, the guide and the scene reference that lead nowhere."""
    broken = []
    for page in [source / "README.md", *sorted((source / "docs").glob("*.md")),
                 source / "scenes" / "README.md"]:
        for match in re.finditer(r"\]\(([^)\s]+)\)", page.read_text()):
            target = match.group(1).split("#")[0]
            if target and not target.startswith(("http:", "https:", "mailto:")) and \
                    not (page.parent / target).exists():
                broken.append(f"{page.relative_to(source)}: a link to {match.group(1)}")
    return broken


def examples_not_shown(source):
    """docs/examples/ files (compiled and run in CI) that no page shows as they are."""
    shown = "".join(page.read_text() for page in (source / "docs").glob("*.md"))
    return [f"docs/examples/{example.name} is not shown whole in a ```cpp block of a page"
            for example in sorted((source / "docs" / "examples").glob("*.cpp"))
            if "```cpp\n" + example.read_text() + "```" not in shown]


def main():
    incise, source = sys.argv[1], pathlib.Path(sys.argv[2])
    pages = sorted((source / "docs").glob("*.md"))
    ran = 0
    failures = broken_links(source) + examples_not_shown(source)
    for page in pages:
        count, failed = run_page(incise, source, page)
        if failed:
            # Once more before failing: a command that is wrong fails again; a machine that was
            # momentarily too busy says so here and does not turn CI red.
            print("WARNING: a page failed once, run again:\n" + "\n".join(failed), flush=True)
            count, failed = run_page(incise, source, page)
        ran += count
        failures += failed
    if ran == 0:
        failures.append("no command found in docs/*.md")
    if failures:
        print("\n".join(["FAILED:"] + failures), file=sys.stderr)
        return 1
    print(f"{ran} commands of {len(pages)} pages ran")
    return 0


if __name__ == "__main__":
    sys.exit(main())
