#!/usr/bin/env python3
"""Resident memory of one process by kind of mapping, from a copy of /proc/PID/smaps:
   bench/smaps_kinds.py SMAPS [NAME]"""
import re
import sys

kinds = {}
cur = None
for line in open(sys.argv[1]):
    m = re.match(r'([0-9a-f]+)-([0-9a-f]+) (\S+) \S+ \S+ \S+\s*(.*)', line)
    if m:
        size = (int(m.group(2), 16) - int(m.group(1), 16)) // 1024
        path = m.group(4).strip()
        perms = m.group(3)
        if path == '':
            if perms.startswith('---'):
                kind = 'anon guard pages'
            elif size in (8188, 8192):
                kind = 'anon 8 MiB (thread stacks)'
            elif size in (65536, 65532) or size > 60000:
                kind = 'anon 64 MiB reservations (malloc thread arenas)'
            else:
                kind = 'anon other (arenas grown, pools, mmap allocations)'
        elif path == '[heap]':
            kind = '[heap] (main arena)'
        elif path.startswith('/dev/shm'):
            kind = '/dev/shm'
        elif path.startswith('['):
            kind = path
        elif '.so' in path:
            kind = 'shared libraries'
        else:
            kind = 'executable and other files'
        cur = kind
        kinds.setdefault(kind, [0, 0, 0])
        kinds[kind][0] += 1
        kinds[kind][2] += size
    elif line.startswith('Rss:') and cur:
        kinds[cur][1] += int(line.split()[1])
total = sum(v[1] for v in kinds.values())
name = sys.argv[2] if len(sys.argv) > 2 else sys.argv[1]
print(f"== {name}: Rss by mapping kind, total {total} kB")
for k, v in sorted(kinds.items(), key=lambda x: -x[1][1]):
    print(f"   {v[1]:>8} kB Rss  {v[0]:>4} maps  {v[2]:>9} kB mapped  {k}")
