#!/usr/bin/env python3
"""The top peak-memory sites of a heaptrack_print --print-peaks report, each with its biggest call
path's first frames of our own code (lb::, or a file of this tree):
   bench/heaptrack_sites.py REPORT.txt [TOP] [DEVICES]
DEVICES: divide each site's bytes by it (bytes per device)."""
import re
import sys

text = open(sys.argv[1], errors='replace').read().splitlines()
top = int(sys.argv[2]) if len(sys.argv) > 2 else 25
devices = int(sys.argv[3]) if len(sys.argv) > 3 else 0
units = {'': 1, 'K': 1e3, 'M': 1e6, 'G': 1e9}


def size(s):
    m = re.match(r'([0-9.]+)([KMG]?)', s)
    return float(m.group(1)) * units[m.group(2)]


sites = []
i = 0
while i < len(text):
    m = re.match(r'^([0-9.]+[KMG]?)B? peak memory consumed over (\d+) calls from', text[i])
    if not m:
        i += 1
        continue
    total, calls = size(m.group(1)), int(m.group(2))
    alloc = text[i + 1].strip()
    ours, lib = [], []
    j = i + 2
    # the first sub-path ("consumed over ... calls from:") is the biggest
    while j < len(text) and 'consumed over' not in text[j]:
        j += 1
    j += 1
    while j < len(text) and text[j].startswith('    ') and 'consumed over' not in text[j] and 'peak memory consumed' not in text[j]:
        line = text[j].strip()
        if not (line.startswith('in ') or line.startswith('at ')):
            frame = re.sub(r'\(.*', '', line)
            at = text[j + 1].strip() if j + 1 < len(text) and text[j + 1].strip().startswith('at ') else ''
            if frame.startswith('lb::') or '/bridge/' in at:
                ours.append(frame + (' ' + at.split('/')[-1] if at else ''))
            elif not ours and len(lib) < 2:
                lib.append(frame)
        j += 1
    sites.append((total, calls, alloc, lib, ours))
    i = j
sites.sort(key=lambda s: -s[0])
for total, calls, alloc, lib, ours in sites[:top]:
    per = f", {total / devices / 1024:.1f} KiB/device" if devices else ''
    print(f"{total / 1e6:8.2f} MB {calls:>8} calls{per}  {alloc}")
    print(f"      via {' <- '.join(lib)}")
    print(f"      ours: {' <- '.join(ours[:3]) if ours else '(none)'}")
