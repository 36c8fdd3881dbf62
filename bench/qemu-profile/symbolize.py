#!/usr/bin/env python3
"""Per-function table of a profile written by profile.c.

    symbolize.py ELF PROFILE [PIXELS] [TOP] [CALLEE...]

Attributes the instructions of each translation block to the function holding its first
instruction (`nm -n -S --demangle` on ELF), and prints the functions by instructions spent,
with their share and, when PIXELS is given, instructions per output pixel. For each CALLEE
(a substring of a function name), also lists its callers with the number of calls.
"""
import bisect
import re
import subprocess
import sys


def functions(elf):
    out = subprocess.run(["nm", "-n", "-S", "--demangle", elf], capture_output=True,
                         text=True, check=True).stdout
    funcs = []
    for line in out.splitlines():
        m = re.match(r"([0-9a-f]+) ([0-9a-f]+) [tTwW] (.*)", line)
        if m:
            start = int(m.group(1), 16) & ~1
            funcs.append((start, start + int(m.group(2), 16), m.group(3)))
    funcs.sort()
    return funcs


def short(name):
    name = re.sub(r"::h[0-9a-f]{16}$", "", name)
    name = name.replace("decoder_core::", "")
    return name if len(name) < 90 else name[:87] + "..."


def main():
    elf, prof = sys.argv[1], sys.argv[2]
    pixels = int(sys.argv[3]) if len(sys.argv) > 3 else 0
    top = int(sys.argv[4]) if len(sys.argv) > 4 else 25
    funcs = functions(elf)
    starts = [f[0] for f in funcs]
    per = {}
    total = 0
    def func_of(addr):
        i = bisect.bisect_right(starts, addr) - 1
        if i >= 0 and funcs[i][0] <= addr < max(funcs[i][1], funcs[i][0] + 1):
            return i
        return None

    calls = {}
    for line in open(prof):
        parts = line.split()
        if parts[0] == "total":
            continue
        if parts[0] == "edge":
            src, dst, n = int(parts[1], 16), int(parts[2], 16), int(parts[3])
            j = func_of(dst)
            if j is not None and funcs[j][0] == dst:
                i = func_of(src)
                caller = short(funcs[i][2]) if i is not None else "?"
                key = (short(funcs[j][2]), caller)
                calls[key] = calls.get(key, 0) + n
            continue
        addr, count = int(parts[0], 16), int(parts[2])
        i = bisect.bisect_right(starts, addr) - 1
        name = "?"
        if i >= 0 and funcs[i][0] <= addr < max(funcs[i][1], funcs[i][0] + 1):
            name = funcs[i][2]
        per[short(name)] = per.get(short(name), 0) + count
        total += count
    print(f"| function | instructions | share |" + (" instr/pixel |" if pixels else ""))
    print("|---|---:|---:|" + ("---:|" if pixels else ""))
    for name, n in sorted(per.items(), key=lambda kv: -kv[1])[:top]:
        row = f"| `{name}` | {n} | {100 * n / total:.1f}% |"
        if pixels:
            row += f" {n / pixels:.1f} |"
        print(row)
    print(f"| total | {total} | 100% |" + (f" {total / pixels:.1f} |" if pixels else ""))
    for want in sys.argv[5:]:
        print(f"\ncallers of {want}:")
        for (callee, caller), n in sorted(calls.items(), key=lambda kv: -kv[1]):
            if want in callee:
                print(f"  {n:>10}  {caller} -> {callee}")


if __name__ == "__main__":
    main()
