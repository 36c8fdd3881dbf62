#!/usr/bin/env python3
"""Disassembly of one function with the instructions executed per translation block.

    annotate.py ELF PROFILE FUNCTION-SUBSTRING

Each line of the function's disassembly (llvm-objdump) is prefixed with the number of times
the translation block starting there was executed and the instructions executed in it (from
profile.c's output), so that hot loops show.
"""
import re
import subprocess
import sys


def main():
    elf, prof, want = sys.argv[1], sys.argv[2], sys.argv[3]
    execs = {}
    spent = {}
    for line in open(prof):
        p = line.split()
        if p[0] in ("total", "edge"):
            continue
        addr, insns, count = int(p[0], 16), int(p[1]), int(p[2])
        execs[addr] = execs.get(addr, 0) + count // max(insns, 1)
        spent[addr] = spent.get(addr, 0) + count
    out = subprocess.run(["llvm-objdump", "-d", "--no-show-raw-insn", "-C", elf],
                         capture_output=True, text=True, check=True).stdout
    on = False
    for line in out.splitlines():
        m = re.match(r"([0-9a-f]+) <(.*)>:", line)
        if m:
            on = want in m.group(2)
            if on:
                print(line)
            continue
        if not on:
            continue
        m = re.match(r"\s*([0-9a-f]+):", line)
        a = int(m.group(1), 16) if m else None
        n = execs.get(a, "")
        t = spent.get(a, "")
        print(f"{n!s:>9} {t!s:>9} {line}")


if __name__ == "__main__":
    main()
