#!/usr/bin/env python3
"""Reads the vector table of the built firmware ELF and checks that every
exception and interrupt ends in the safe state unless the firmware serves it.

    python3 check.py ELF PAC_RS LLVM_BIN_DIR

- ELF: target/thumbv7em-none-eabihf/release/cylinder-servo
- PAC_RS: stm32-metapac's chips/<chip>/pac.rs (its `enum Interrupt` names
  the device's vector slots)
- LLVM_BIN_DIR: the toolchain's llvm-tools (llvm-nm, llvm-objdump)

Rules (exit 1 on the first broken one, with every offence listed):
1. Slot 1 is `Reset`, slot 3 `HardFault` (the firmware's own, no trampoline).
2. Each interrupt the firmware serves (SERVED below) points at its handler of
   the same name, not at DefaultHandler.
3. Every other slot (NMI, MemManage, BusFault, UsageFault, SVCall,
   DebugMonitor, PendSV, SysTick and every other device interrupt) points at
   DefaultHandler; a zero entry is allowed only in a reserved slot.
4. DefaultHandler and HardFault both reach `safe_state` (a direct branch or
   call, through at most two calls in between), and `safe_state` stores to
   TIM1 (0x4001_2C00, BDTR) and to GPIOB (0x4800_0400, BSRR).
`--self-test` also runs the rules on tables broken on purpose and fails if a
rule lets one pass.
"""
import re
import struct
import subprocess
import sys

# The interrupts the image serves, each with its reason. Adding a driver that
# binds another interrupt means adding it here (with its reason), in review.
SERVED = {
    "ADC1_2": "the PWM interrupt: the current loop (src/board/b_g431b_esc1/isr.rs)",
    "TIM2": "embassy's time driver (feature time-driver-tim2)",
    "USART2": "the ST-LINK virtual COM port (comms.rs)",
    "DMA1_CHANNEL1": "USART2 transmit DMA (comms.rs)",
    "DMA1_CHANNEL2": "USART2 receive DMA ring (comms.rs)",
    "FDCAN1_IT0": "FDCAN1 receive and errors (comms.rs)",
    "FDCAN1_IT1": "FDCAN1 transmit (comms.rs)",
}
SYSTEM = {
    1: "Reset", 2: "NonMaskableInt", 3: "HardFault", 4: "MemoryManagement",
    5: "BusFault", 6: "UsageFault", 11: "SVCall", 12: "DebugMonitor",
    14: "PendSV", 15: "SysTick",
}
TIM1_BASE = 0x4001_2C00
GPIOB_BASE = 0x4800_0400


def run(*cmd):
    return subprocess.run(cmd, check=True, capture_output=True, text=True).stdout


def device_interrupts(pac_rs):
    text = open(pac_rs).read()
    body = re.search(r"pub enum Interrupt \{(.*?)\n\}", text, re.S)
    if not body:
        sys.exit(f"error: no `enum Interrupt` in {pac_rs}")
    return {int(n): name for name, n in re.findall(r"^\s*(\w+) = (\d+),", body.group(1), re.M)}


def vector_table(elf, llvm):
    out = run(f"{llvm}/llvm-objdump", "-s", "-j", ".vector_table", elf)
    data = b""
    for line in out.splitlines():
        m = re.match(r"^ ([0-9a-f]+) ((?:[0-9a-f]{8} ?){1,4})", line)
        if m:
            data += bytes.fromhex(m.group(2).replace(" ", ""))
    if len(data) < 16 * 4:
        sys.exit(f"error: no .vector_table in {elf}")
    return list(struct.unpack(f"<{len(data) // 4}I", data))


def symbols(elf, llvm):
    by_name, by_addr = {}, {}
    for line in run(f"{llvm}/llvm-nm", "--defined-only", elf).splitlines():
        parts = line.split()
        if len(parts) == 3:
            addr, name = int(parts[0], 16) & ~1, parts[2]
            by_name[name] = addr
            by_addr.setdefault(addr, set()).add(name)
    return by_name, by_addr


def slot_names(n_slots, irqs):
    names = dict(SYSTEM)
    for irq, name in irqs.items():
        names[16 + irq] = name
    return {i: names.get(i) for i in range(1, n_slots)}


def check_table(table, names, by_name, by_addr):
    """The offences of rules 1-3, as lines of text."""
    bad = []
    default = by_name.get("DefaultHandler")
    if default is None:
        return ["no DefaultHandler symbol"]
    for slot, name in names.items():
        entry = table[slot] if slot < len(table) else 0
        target = entry & ~1
        at = ", ".join(sorted(by_addr.get(target, {"?"})))
        if name is None:
            if entry not in (0, default | 1):
                bad.append(f"slot {slot} (reserved) -> 0x{entry:08x} ({at})")
            continue
        if name in ("Reset", "HardFault") or name in SERVED:
            own = by_name.get(name)
            if own is None or target != own or target == default:
                bad.append(f"slot {slot} {name}: 0x{entry:08x} ({at}) is not the firmware's {name} handler")
            continue
        if entry == 0:
            bad.append(f"slot {slot} {name}: zero entry (a fault on entry, not the safe state)")
        elif target != default:
            bad.append(f"slot {slot} {name} -> 0x{entry:08x} ({at}), not DefaultHandler")
    return bad


def calls(elf, llvm, symbol):
    """Symbols that `symbol` branches to or calls directly."""
    out = run(f"{llvm}/llvm-objdump", "-d", "--no-show-raw-insn", f"--disassemble-symbols={symbol}", elf)
    return set(re.findall(r"\tb(?:l|\.w|)\s+0x[0-9a-f]+ <([^>+]+)", out)), out


def reaches(elf, llvm, start, goal, depth=3):
    seen, frontier = set(), {start}
    for _ in range(depth):
        nxt = set()
        for sym in frontier:
            if sym in seen:
                continue
            seen.add(sym)
            targets, _ = calls(elf, llvm, sym)
            if goal in targets:
                return True
            nxt |= targets
        frontier = nxt
    return False


def word_at(elf, addr):
    """The 32-bit word at `addr` in the ELF's allocated sections."""
    data = open(elf, "rb").read()
    shoff, = struct.unpack_from("<I", data, 0x20)
    shentsize, shnum = struct.unpack_from("<HH", data, 0x2E)
    for i in range(shnum):
        _, sh_type, _, sh_addr, sh_offset, sh_size = struct.unpack_from("<IIIIII", data, shoff + i * shentsize)
        if sh_type == 1 and sh_addr <= addr < sh_addr + sh_size:  # PROGBITS
            return struct.unpack_from("<I", data, sh_offset + addr - sh_addr)[0]
    return 0


def check_handlers(elf, llvm, by_name):
    bad = []
    if "safe_state" not in by_name:
        return ["no safe_state symbol in the image"]
    for handler in ("DefaultHandler", "HardFault"):
        if not reaches(elf, llvm, handler, "safe_state"):
            bad.append(f"{handler} does not reach safe_state")
    _, body = calls(elf, llvm, "safe_state")
    # Register addresses come from the literal pool (`ldr rN, [pc, #k] @ 0xADDR`)
    # or from movw/movt pairs.
    addrs = set()
    for lit in re.findall(r"ldr\s+r\d+, \[pc, #0x[0-9a-f]+\]\s+@ 0x([0-9a-f]+)", body):
        addrs.add(word_at(elf, int(lit, 16)))
    halves = re.findall(r"mov[wt]\s+r\d+, #0x([0-9a-f]+)", body)
    for lo, hi in zip(halves[::2], halves[1::2]):
        addrs.add(int(lo, 16) | (int(hi, 16) << 16))
    if not any(TIM1_BASE <= a < TIM1_BASE + 0x400 for a in addrs):
        bad.append("safe_state does not address TIM1 (main output off)")
    if not any(GPIOB_BASE <= a < GPIOB_BASE + 0x400 for a in addrs):
        bad.append("safe_state does not address GPIOB (brake pin low)")
    return bad


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    self_test = "--self-test" in sys.argv
    if len(args) != 3:
        sys.exit(__doc__)
    elf, pac_rs, llvm = args
    irqs = device_interrupts(pac_rs)
    table = vector_table(elf, llvm)
    by_name, by_addr = symbols(elf, llvm)
    names = slot_names(len(table), irqs)
    for name in SERVED:
        if name not in irqs.values():
            sys.exit(f"error: served interrupt {name} is not one of this chip's")

    served = [f"  slot {s:3} {n:<16} -> {', '.join(sorted(by_addr.get(table[s] & ~1, {'?'})))}"
              for s, n in names.items() if n in SERVED or n in ("Reset", "HardFault")]
    to_default = sum(1 for s, n in names.items() if n and table[s] & ~1 == by_name.get("DefaultHandler"))
    print(f"vector table of {elf}: {len(table)} entries")
    print("\n".join(served))
    print(f"  {to_default} exception and interrupt slots -> DefaultHandler (safe state)")

    bad = check_table(table, names, by_name, by_addr) + check_handlers(elf, llvm, by_name)
    status = 0
    if bad:
        print("vectors: FAILED:")
        print("\n".join("  " + b for b in bad))
        status = 1
    else:
        print("vectors: every unserved exception and interrupt ends in safe_state")

    if self_test:
        slot_of = {n: s for s, n in names.items() if n}
        cases = {
            "an unserved interrupt bound to a handler": ("EXTI0", by_name["ADC1_2"] | 1),
            "NMI pointing elsewhere": ("NonMaskableInt", by_name["Reset"] | 1),
            "a served interrupt left on DefaultHandler": ("ADC1_2", by_name["DefaultHandler"] | 1),
            "a zero entry in a device slot": ("TIM1_BRK_TIM15", 0),
            "SysTick bound to a handler": ("SysTick", by_name["TIM2"] | 1),
        }
        for what, (name, value) in cases.items():
            broken = list(table)
            broken[slot_of[name]] = value
            caught = check_table(broken, names, by_name, by_addr)
            print(f"  self-test: {what}: {'caught' if caught else 'MISSED'}")
            if not caught:
                status = 1
    sys.exit(status)


if __name__ == "__main__":
    main()
