#!/usr/bin/env python3
"""Runs every command of the user guide's ```sh blocks (docs/*.md), in order, page by page, in
a scratch folder that links to the repository's scenes/: each must exit 0. `incise` at the start
of a line is the built program.

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


def main():
    incise, source = sys.argv[1], pathlib.Path(sys.argv[2])
    pages = sorted((source / "docs").glob("*.md"))
    ran = 0
    failures = []
    for page in pages:
        with tempfile.TemporaryDirectory() as scratch:
            os.symlink(source / "scenes", os.path.join(scratch, "scenes"))
            for command in commands(page):
                words = shlex.split(command)
                if words[0] == "incise":
                    words[0] = incise
                result = subprocess.run(words, cwd=scratch, capture_output=True, text=True,
                                        timeout=600)
                ran += 1
                print(f"{page.name}: {command}: exit {result.returncode}", flush=True)
                if result.returncode != 0:
                    failures.append(f"{page.name}: {command}\n{result.stderr[-2000:]}")
    if ran == 0:
        failures.append("no command found in docs/*.md")
    if failures:
        print("\n".join(["FAILED:"] + failures), file=sys.stderr)
        return 1
    print(f"{ran} commands of {len(pages)} pages ran")
    return 0


if __name__ == "__main__":
    sys.exit(main())
