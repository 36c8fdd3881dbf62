#!/usr/bin/env python3
"""Stack frame of every function of an ARM ELF, from its prologue (`push` registers and
`sub sp, #n`), largest first: where a decoder's stack goes.

    frames.py ELF [FILTER]
"""
import re
import subprocess
import sys


def main():
    elf = sys.argv[1]
    want = sys.argv[2] if len(sys.argv) > 2 else ""
    out = subprocess.run(["llvm-objdump", "-d", "--no-show-raw-insn", "-C", elf],
                         capture_output=True, text=True, check=True).stdout
    frames = {}
    name = None
    seen = 0
    for line in out.splitlines():
        m = re.match(r"[0-9a-f]+ <(.*)>:", line)
        if m:
            name = m.group(1)
            frames[name] = 0
            seen = 0
            continue
        if name is None or seen > 12:
            continue
        seen += 1
        ins = line.split("\t")
        if len(ins) < 3:
            continue
        op, args = ins[1].strip(), ins[2].strip() if len(ins) > 2 else ""
        if op.startswith("push"):
            regs = 0
            for part in args.strip("{}").split(","):
                part = part.strip()
                if "-" in part:
                    a, b = part.split("-")
                    regs += int(b[1:]) - int(a[1:]) + 1 if a[1:].isdigit() and b[1:].isdigit() else 1
                elif part:
                    regs += 1
            frames[name] += 4 * regs
        elif op.startswith("sub") and args.startswith("sp"):
            m = re.search(r"#(0x[0-9a-f]+|\d+)", args)
            if m:
                frames[name] += int(m.group(1), 0)
        elif op.startswith("vpush"):
            frames[name] += 8 * args.count("d")
    for n, f in sorted(frames.items(), key=lambda kv: -kv[1]):
        if want in n and f > 0:
            print(f"{f:6d}  {n[:120]}")


if __name__ == "__main__":
    main()
