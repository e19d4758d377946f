#!/usr/bin/env python3
"""clang-tidy over the translation units of a compile_commands.json that match a regular
expression, skipping a unit that was already found clean with the very same input.

The key of a unit is what decides clang-tidy's answer: the clang-tidy version, .clang-tidy, the
header filter, the unit's compile command and the unit preprocessed by clang (every header's text
that reaches it), with the checkout's root path written as a placeholder so that two clones of one
commit share their entries (ccache's preprocessor mode, for clang-tidy). Only clean units are
recorded: a unit with a finding runs again every time. A fresh machine has no cache and tidies
every unit.

  clang_tidy_cached.py --build DIR --root DIR --units REGEX --header-filter REGEX
                       [--jobs N] [--cache DIR | --cache 0]
Prints clang-tidy's output for the units it ran and one summary line on stderr; exits 1 when a
clang-tidy run failed (its findings are on stdout either way).
"""
import argparse
import concurrent.futures
import hashlib
import json
import os
import pathlib
import re
import shlex
import subprocess
import sys


def unit_arguments(entry):
    if "arguments" in entry:
        return list(entry["arguments"])
    return shlex.split(entry["command"])


def preprocess_arguments(args):
    """The compile command as clang's preprocessor: no output file, no compile, no warnings."""
    out = ["clang++"]
    skip = False
    for a in args[1:]:
        if skip:
            skip = False
            continue
        if a == "-o":
            skip = True
            continue
        if a in ("-c",) or a.startswith("-W"):
            continue
        out.append(a)
    return out + ["-E", "-P", "-w", "-o", "-"]


def unit_key(entry, fixed, root):
    args = unit_arguments(entry)
    pre = subprocess.run(preprocess_arguments(args), cwd=entry["directory"], capture_output=True)
    if pre.returncode != 0:
        return None  # clang-tidy will say why; never cache what could not be read
    h = hashlib.sha256(fixed)
    for part in (" ".join(args), entry["file"]):
        h.update(part.replace(root, "@ROOT@").encode())
    h.update(pre.stdout.replace(root.encode(), b"@ROOT@"))
    return h.hexdigest()


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--build", required=True)
    p.add_argument("--root", required=True)
    p.add_argument("--units", required=True)
    p.add_argument("--header-filter", required=True)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--cache", default=os.path.join(
        os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache")), "linebridge", "clang-tidy"))
    o = p.parse_args()

    root = os.path.realpath(o.root)
    units_re = re.compile(o.units)
    entries = [e for e in json.load(open(os.path.join(o.build, "compile_commands.json")))
               if units_re.search(e["file"])]
    tidy = ["clang-tidy", "-p", o.build, "-quiet", "-extra-arg=-Wno-unknown-warning-option",
            f"-header-filter={o.header_filter}"]
    use_cache = o.cache != "0"
    fixed = b""
    if use_cache:
        version = subprocess.run(["clang-tidy", "--version"], capture_output=True, check=True).stdout
        config = pathlib.Path(root, ".clang-tidy").read_bytes()
        fixed = version + config + o.header_filter.replace(root, "@ROOT@").encode()
        pathlib.Path(o.cache).mkdir(parents=True, exist_ok=True)

    def run(entry):
        key = unit_key(entry, fixed, root) if use_cache else None
        if key and pathlib.Path(o.cache, key).exists():
            return entry["file"], "cached", b""
        r = subprocess.run(tidy + [entry["file"]], capture_output=True)
        # clang-tidy prints findings on stdout; "N warnings generated" noise on stderr.
        clean = r.returncode == 0 and not re.search(rb": (warning|error): ", r.stdout)
        if key and clean:
            pathlib.Path(o.cache, key).touch()
        return entry["file"], ("clean" if clean else "findings"), r.stdout + (b"" if r.returncode == 0 else r.stderr)

    failed = 0
    counts = {"cached": 0, "clean": 0, "findings": 0}
    with concurrent.futures.ThreadPoolExecutor(max_workers=o.jobs) as pool:
        for _, verdict, output in pool.map(run, entries):
            counts[verdict] += 1
            if verdict == "findings":
                failed = 1
            sys.stdout.buffer.write(output)
    print(f"clang_tidy_cached: {len(entries)} units: {counts['clean']} tidied clean, "
          f"{counts['findings']} with findings, {counts['cached']} unchanged since a clean run "
          f"({'cache ' + o.cache if use_cache else 'no cache'})", file=sys.stderr)
    return failed


if __name__ == "__main__":
    sys.exit(main())
