#!/usr/bin/env bash
# FHPP on a Festo CMMO-ST from a shell with mbpoll, as a commissioning engineer does it (FHPP
# manual Tab. 5.13; its extract kept beside the project, spec/cmmo-st-fhpp.md §2.5): the output
# telegram is holding registers 0…3 (CCON CPOS | byte 3 byte 4 | set-point, big-endian), the
# input telegram reads back from the same registers (SCON SPOS | … | actual position). Enable,
# home on the current position, move in direct mode to TARGET and wait for MC; exit 0 when the
# axis is there.
# Usage: fhpp_mbpoll.sh HOST PORT [TARGET]   (TARGET in SINC, 0.01° by default)
set -euo pipefail
host=$1 port=$2 target=${3:-27000}

mb() { mbpoll -m tcp -p "$port" -a 1 -0 -r 0 -1 -o 1 "$@"; }
# Writes the output telegram: CCON CPOS byte3 byte4 set-point.
write_out() {
  local sp=$(( $5 & 0xFFFFFFFF ))
  mb -t 4:hex "$host" $(( ($1 << 8) | $2 )) $(( ($3 << 8) | $4 )) $(( sp >> 16 )) $(( sp & 0xFFFF )) >/dev/null
}
# Reads the input telegram into SCON SPOS ACTUAL.
read_in() {
  local regs
  regs=$(mb -t 4:hex -c 4 "$host" | sed -n 's/^\[[0-3]\]:[[:space:]]*0x\([0-9A-Fa-f]*\)$/\1/p')
  set -- $regs
  [ $# -eq 4 ] || { echo "no input telegram from $host:$port" >&2; return 1; }
  SCON=$(( 0x$1 >> 8 )) SPOS=$(( 0x$1 & 0xFF ))
  ACTUAL=$(( (0x$3 << 16) | 0x$4 ))
  (( ACTUAL >= 0x80000000 )) && ACTUAL=$(( ACTUAL - 0x100000000 ))
  return 0
}
# Polls the input telegram until the arithmetic test $1 holds (at most 300 reads).
until_status() {
  for _ in $(seq 300); do
    read_in
    if (( $1 )); then return 0; fi
  done
  printf 'gave up waiting for %s: SCON %02Xh SPOS %02Xh\n' "$1" "$SCON" "$SPOS" >&2
  exit 1
}

read_in
printf 'power-on: SCON %02Xh SPOS %02Xh\n' "$SCON" "$SPOS"
write_out 0x03 0x01 0 0 0                                  # CCON ENABLE STOP, CPOS HALT
until_status 'SCON == 0x13 && SPOS == 0x05'
echo enabled
write_out 0x03 0x05 0 0 0                                  # + CPOS HOM
until_status 'SPOS & 0x80 && SPOS & 0x04'            # REF and MC
write_out 0x03 0x01 0 0 0
until_status '!(SPOS & 0x02)'                        # ACK falls
echo homed
write_out 0x43 0x01 0 100 "$target"                        # direct mode (OPM1), 100 % speed
until_status 'SCON == 0x53'
write_out 0x43 0x03 0 100 "$target"                        # CPOS START
until_status 'SPOS & 0x02'                           # ACK
write_out 0x43 0x01 0 100 "$target"
until_status 'SPOS & 0x04'                           # MC
printf 'reached: actual %d, target %d, SCON %02Xh SPOS %02Xh\n' "$ACTUAL" "$target" "$SCON" "$SPOS"
(( ACTUAL - target <= 180 && target - ACTUAL <= 180 ))
