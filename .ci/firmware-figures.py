#!/usr/bin/env python3
"""The firmware images' figures, read from their ELF files, checked against their budgets.

    firmware-figures.py NAME ELF --flash-budget BYTES --ram-budget BYTES --stack-budget BYTES
                        [--heap-symbol SUBSTRING --heap-high-water BYTES] [--objdump PATH]

Prints, for one image:

- flash: what the part's flash holds, .vector_table + .text + .rodata (+ .data, its initial
  values; none of the images has any);
- static RAM: .data + .bss (+ .uninit), everything the linker placed in RAM;
- the heap: the arena given to the allocator (the size of the symbol whose name contains
  --heap-symbol) and the high-water mark measured on the host; the RAM the image needs is its
  static RAM without the arena plus the high-water mark, and the arena must hold the mark;
- the stack: the deepest chain of stack frames from the reset handler through direct calls, read
  from the disassembly (each function's pushes and stack-pointer subtractions; calls through
  pointers are listed, not followed), and what the part's RAM leaves for it; the same from the
  board's main loop (`Board::run`), so that what start-up needs beyond it shows;
- the RAM the image needs with its stack: the RAM above plus the deepest stack (an image may
  keep its largest value in the frame of `main`, which never returns, rather than in a static).

Exits 1 if a budget is exceeded (flash, RAM with the stack, the start-up stack), the arena is smaller than the
mark, or the stack does not fit.
No dependency beyond Python and llvm-objdump (rustup's llvm-tools component).
"""
import argparse
import re
import struct
import subprocess
import sys

# The part's RAM (STM32F413: 320 KiB), where .data/.bss start and the stack ends.
RAM_BYTES = 320 * 1024


def sections_and_symbols(path):
    """{section name: size} and [(symbol name, size)] of a 32-bit little-endian ELF."""
    data = open(path, "rb").read()
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        sys.exit(f"{path}: not a 32-bit little-endian ELF")
    shoff, = struct.unpack_from("<I", data, 0x20)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x2E)
    heads = [struct.unpack_from("<IIIIIIIIII", data, shoff + i * shentsize) for i in range(shnum)]
    names_off = heads[shstrndx][4]

    def cstr(off):
        return data[off:data.index(b"\0", off)].decode()

    sections = {cstr(names_off + h[0]): h for h in heads}
    sizes = {name: h[5] for name, h in sections.items()}
    symbols = []
    if ".symtab" in sections:
        sym = sections[".symtab"]
        strtab = heads[sym[6]][4]
        for i in range(sym[5] // 16):
            name, _value, size, _info, _other, _shndx = struct.unpack_from("<IIIBBH", data, sym[4] + i * 16)
            symbols.append((cstr(strtab + name), size))
    return sizes, symbols


FUNC = re.compile(r"^([0-9a-f]+) <(.+)>:$")
PUSH = re.compile(r"\b(push|stmdb)(\.w)?\s+(sp!,\s*)?\{([^}]*)\}")
VPUSH = re.compile(r"\bvpush\s+\{([^}]*)\}")
SUB_SP = re.compile(r"\bsub(\.w|w)?\s+sp,\s*(sp,\s*)?#(0x[0-9a-f]+|\d+)")
CALL = re.compile(r"\bbl\s+0x[0-9a-f]+\s+<([^>+]+)>")
TAIL = re.compile(r"\bb(\.w)?\s+0x[0-9a-f]+\s+<([^>+]+)>")
INDIRECT = re.compile(r"\bblx\s+r\d+")


def registers(spec):
    """How many registers a register list names ({r4, r5, lr}, {d8-d9})."""
    n = 0
    for part in spec.split(","):
        part = part.strip()
        if "-" in part:
            lo, hi = (int(re.sub(r"\D", "", x)) for x in part.split("-"))
            n += hi - lo + 1
        elif part:
            n += 1
    return n


def functions(elf, objdump):
    """{function: (frame bytes, set of callees, calls through pointers)} from the disassembly."""
    out = subprocess.run([objdump, "-d", "-C", "--no-show-raw-insn", elf], capture_output=True, text=True, check=True).stdout
    funcs = {}
    name = None
    for line in out.splitlines():
        m = FUNC.match(line.strip())
        if m:
            # `$d` and `$t` mark data and code inside a function, not a new one.
            if not m.group(2).startswith("$"):
                name = m.group(2)
                funcs[name] = [0, set(), 0]
            continue
        if name is None:
            continue
        f = funcs[name]
        if m := PUSH.search(line):
            f[0] += 4 * registers(m.group(4))
        elif m := VPUSH.search(line):
            f[0] += 8 * registers(m.group(1))
        elif m := SUB_SP.search(line):
            f[0] += int(m.group(3), 0)
        if m := CALL.search(line):
            f[1].add(m.group(1))
        elif (m := TAIL.search(line)) and m.group(2) != name and not m.group(2).startswith(name + "+"):
            f[1].add(m.group(2))
        if INDIRECT.search(line):
            f[2] += 1
    return funcs


def deepest(funcs, root):
    """(bytes, chain) of the deepest stack from `root` through direct calls (recursion cut)."""
    memo = {}

    def walk(fn, seen):
        if fn in memo:
            return memo[fn]
        frame, callees, _ = funcs.get(fn, (0, set(), 0))
        best = (0, [])
        for c in sorted(callees):
            if c in seen or c not in funcs:
                continue
            got = walk(c, seen | {c})
            if got[0] > best[0]:
                best = got
        memo[fn] = (frame + best[0], [(fn, frame)] + best[1])
        return memo[fn]

    return walk(root, {root})


def short(fn):
    """A function's path without its generics and hash: `master_board::board::build`."""
    fn = re.sub(r"::h[0-9a-f]{16}$", "", fn)
    for code, ch in (("$LT$", "<"), ("$GT$", ">"), ("$u20$", " "), ("$C$", ","), ("..", "::")):
        fn = fn.replace(code, ch)
    depth, out = 0, ""
    for ch in fn:
        depth += ch == "<"
        if depth == 0:
            out += ch
        depth -= ch == ">"
    return out


def kib(n):
    return f"{n:,} bytes ({n / 1024:.1f} KiB)"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("name")
    ap.add_argument("elf")
    ap.add_argument("--flash-budget", type=int, required=True)
    ap.add_argument("--ram-budget", type=int, required=True)
    ap.add_argument("--stack-budget", type=int, required=True)
    ap.add_argument("--heap-symbol")
    ap.add_argument("--heap-high-water", type=int)
    ap.add_argument("--objdump", default="llvm-objdump")
    a = ap.parse_args()

    sizes, symbols = sections_and_symbols(a.elf)
    flash = sum(sizes.get(s, 0) for s in (".vector_table", ".text", ".rodata", ".data"))
    static = sum(sizes.get(s, 0) for s in (".data", ".bss", ".uninit"))
    print(f"{a.name}: flash {kib(flash)}: .text {sizes.get('.text', 0):,} + .rodata {sizes.get('.rodata', 0):,}"
          f" + vector table {sizes.get('.vector_table', 0):,}")
    print(f"{a.name}: static RAM {kib(static)}: .data {sizes.get('.data', 0):,} + .bss {sizes.get('.bss', 0):,}")
    failed = []
    if flash > a.flash_budget:
        failed.append(f"flash {flash:,} > budget {a.flash_budget:,}")
    print(f"{a.name}: flash budget {kib(a.flash_budget)}: {'ok' if flash <= a.flash_budget else 'EXCEEDED'}")

    need = static
    if a.heap_symbol:
        arena = max((size for name, size in symbols if a.heap_symbol in name), default=None)
        if arena is None:
            sys.exit(f"{a.name}: no symbol containing {a.heap_symbol!r}: where is the heap?")
        mark = a.heap_high_water or 0
        need = static - arena + mark
        print(f"{a.name}: heap arena {kib(arena)} (in .bss); high-water mark on the host {kib(mark)}")
        print(f"{a.name}: RAM needed, static without the arena + high-water mark: {kib(need)}")
        if mark > arena:
            failed.append(f"heap high-water {mark:,} > arena {arena:,}")

    funcs = functions(a.elf, a.objdump)
    # cortex-m-rt's reset handler (`Reset`, `__stext` in its assembly start-up).
    root = next((r for r in ("Reset", "__stext") if r in funcs), None)
    if root is None:
        sys.exit(f"{a.name}: no reset handler in the disassembly")
    depth, chain = deepest(funcs, root)
    room = RAM_BYTES - static
    top = ", ".join(f"{short(fn)} {frame:,}" for fn, frame in chain if frame >= 256)
    indirect = sum(f[2] for f in funcs.values())
    print(f"{a.name}: deepest stack through direct calls {kib(depth)} ({top}); "
          f"{indirect} calls through pointers not followed; room for the stack {kib(room)}")
    # The main loop: the board's `run`, called from `main` (whose frame both share).
    run = next((fn for fn in funcs if short(fn).endswith("Board::run")), None)
    if run is not None:
        main = next((fn for fn, _ in chain if short(fn).endswith("__cortex_m_rt_main")), None)
        loop = deepest(funcs, run)[0] + (funcs[main][0] if main else 0)
        print(f"{a.name}: the main loop's stack {kib(loop)} (main's frame and Board::run's deepest); "
              f"start-up needs {kib(max(depth - loop, 0))} beyond it")
    if depth > room:
        failed.append(f"stack {depth:,} > room {room:,}")
    if depth > a.stack_budget:
        failed.append(f"stack {depth:,} > budget {a.stack_budget:,}")
    print(f"{a.name}: stack budget {kib(a.stack_budget)}: {'ok' if depth <= a.stack_budget else 'EXCEEDED'}")
    # The RAM budget counts the stack: the images build their machines in `main`'s frame, so
    # statics alone would leave out most of what the board must hold.
    total = need + depth
    print(f"{a.name}: RAM needed with the stack, {kib(need)} + the deepest stack: {kib(total)}")
    if total > a.ram_budget:
        failed.append(f"RAM with the stack {total:,} > budget {a.ram_budget:,}")
    print(f"{a.name}: RAM budget {kib(a.ram_budget)}: {'ok' if total <= a.ram_budget else 'EXCEEDED'}")

    for f in failed:
        print(f"{a.name}: FAILED: {f}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
