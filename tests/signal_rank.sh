#!/bin/sh
# signal_rank.sh SIGNAL RANK DELAY COMMAND...: runs an mpirun COMMAND, sends SIGNAL to the
# process of RANK after DELAY seconds, and exits with the command's status (its output as is).
signal=$1 rank=$2 delay=$3
shift 3
"$@" &
launcher=$!
sleep "$delay"
sent=0
for pid in $(pgrep -P "$launcher"); do
  if tr '\0' '\n' < /proc/"$pid"/environ 2>/dev/null | grep -qx "OMPI_COMM_WORLD_RANK=$rank"; then
    kill -"$signal" "$pid" && sent=1
  fi
done
[ "$sent" = 1 ] || echo "signal_rank.sh: rank $rank was not running after $delay s" >&2
wait "$launcher"
