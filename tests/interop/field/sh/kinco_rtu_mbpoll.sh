#!/usr/bin/env bash
# A Kinco FD3 on its RS485 port (Modbus RTU, 19200 8N1, station 1) from a shell with mbpoll:
# the registers of the Kinco manual's extract kept beside the project (spec/kinco-fd-cd.md
# §2.3: 3100h controlword, 3200h statusword, 3500h Operation_Mode, 4000h Target_Position,
# 4A00h-4C00h profile, 3700h Pos_Actual, 3900h the position window; 32-bit values low word
# first, mbpoll's own word order). Profile position:
# enable with 06h, 07h, 0Fh (each after its answer), move with 2Fh → 3Fh, poll until target
# reached at the target; exit 0 when the axis is there. The controlword and the mode must be
# free of the factory inputs (Din1/Din3_Function = 0, as a commissioned drive has them).
# Usage: kinco_rtu_mbpoll.sh DEVICE [TARGET]
set -euo pipefail
dev=$1 target=${2:-50000}

mb() { mbpoll -m rtu -b 19200 -P none -a 1 -0 -1 -o 0.5 "$@"; }
w16() { mb -t 4:hex -r "$1" "$dev" "$2" >/dev/null; }
w32() { mb -t 4:int -r "$1" "$dev" -- "$2" >/dev/null; }
# One value: 16-bit register (hex) or 32-bit (int) at $2.
r16() { echo $(( $(mb -t 4:hex -r "$1" "$dev" | sed -n 's/^\[[0-9]*\]:[[:space:]]*//p') )); }
r32() { mb -t 4:int -r "$1" "$dev" | sed -n 's/^\[[0-9]*\]:[[:space:]]*//p'; }
# Polls the statusword until the arithmetic test $1 on SW holds (at most 200 reads).
until_sw() {
  for _ in $(seq 200); do
    SW=$(r16 0x3200)
    if (( $1 )); then return 0; fi
  done
  printf 'gave up waiting for %s: statusword %04Xh\n' "$1" "$SW" >&2
  exit 1
}

w16 0x3500 1                      # profile position
w32 0x4A00 1638400                # 600 rpm
w32 0x4B00 16384                  # 100 rps/s
w32 0x4C00 16384
w16 0x3100 0x00
until_sw '(SW & 0x4F) == 0x40'
for cw in 0x06 0x07 0x0F; do w16 0x3100 $cw; done
until_sw '(SW & 0x6F) == 0x27'
echo "enabled: statusword $(printf %04Xh "$SW")"
window=$(r32 0x3900)
w32 0x4000 "$target"
w16 0x3100 0x2F
w16 0x3100 0x3F
for _ in $(seq 200); do
  SW=$(r16 0x3200)
  pos=$(r32 0x3700)
  if (( SW & 0x400 && pos - target <= window && target - pos <= window )); then
    printf 'reached: Pos_Actual %d, target %d, statusword %04Xh\n' "$pos" "$target" "$SW"
    exit 0
  fi
done
printf 'not reached: Pos_Actual %d, target %d, statusword %04Xh\n' "$pos" "$target" "$SW" >&2
exit 1
