"""Waits of real-time threads in an ftrace text trace (scripts/sched-trace): every wake-up of
a thread at a real-time priority (prio < 100) that took over WAIT_MS to run, with the thread
that held the CPU meanwhile, and every CPU that logged no event at all for over SILENT_MS: a
busy CPU takes its scheduler tick every 4 ms (HZ=250), so a longer silence is a CPU the host
did not run (or one with interrupts off)."""
import re
import sys

WAIT_MS = 1.0
SILENT_MS = 4.5
LINE = re.compile(r"^\s*(.+?)-(\d+)\s+\[(\d+)\]\s+\S+\s+([\d.]+): (\w+): (.*)$")
WAKEUP = re.compile(r"comm=(.+?) pid=(\d+) prio=(\d+) target_cpu=(\d+)")
SWITCH = re.compile(r"prev_comm=(.+?) prev_pid=(\d+) .*==> next_comm=(.+?) next_pid=(\d+)")


def main(path: str) -> None:
    woken: dict[int, tuple[float, str, int]] = {}
    last_event: dict[int, float] = {}
    waits = silences = 0
    with open(path, errors="replace") as f:
        for line in f:
            m = LINE.match(line)
            if not m:
                continue
            cpu, t, kind, rest = int(m.group(3)), float(m.group(4)), m.group(5), m.group(6)
            before = last_event.get(cpu)
            if before is not None and (t - before) * 1e3 > SILENT_MS:
                silences += 1
                print(f"cpu{cpu}: no event for {(t - before) * 1e3:.2f} ms from {before:.6f}")
            last_event[cpu] = t
            if kind == "sched_wakeup":
                w = WAKEUP.search(rest)
                if w and int(w.group(3)) < 100:
                    woken[int(w.group(2))] = (t, w.group(1), int(w.group(4)))
            elif kind == "sched_switch":
                s = SWITCH.search(rest)
                if s and int(s.group(4)) in woken:
                    at, comm, target = woken.pop(int(s.group(4)))
                    if (t - at) * 1e3 > WAIT_MS:
                        waits += 1
                        print(f"{comm} ({s.group(4)}) woken {at:.6f} for cpu{target}, ran on "
                              f"cpu{cpu} {(t - at) * 1e3:.2f} ms later, after {s.group(1)}")
    print(f"{waits} real-time waits over {WAIT_MS} ms, {silences} CPU silences over {SILENT_MS} ms")


if __name__ == "__main__":
    main(sys.argv[1])
