#!/bin/sh
# signal_rank.sh SIGNAL RANK DELAY COMMAND...: runs an mpirun COMMAND, sends SIGNAL to the
# process of RANK after DELAY seconds, and exits with the command's status (its output as is).
# Only /proc and the shell: no procps on a bare Debian.
signal=$1 rank=$2 delay=$3
shift 3
"$@" &
launcher=$!
sleep "$delay"
sent=0
for stat in /proc/[0-9]*/stat; do
  pid=${stat#/proc/}
  pid=${pid%/stat}
  # The parent is the second field after the command name's closing parenthesis.
  parent=$(sed 's/.*) //' "$stat" 2>/dev/null | cut -d' ' -f2)
  [ "$parent" = "$launcher" ] || continue
  if tr '\0' '\n' < /proc/"$pid"/environ 2>/dev/null | grep -qx "OMPI_COMM_WORLD_RANK=$rank"; then
    kill -"$signal" "$pid" && sent=1
  fi
done
[ "$sent" = 1 ] || echo "signal_rank.sh: rank $rank was not running after $delay s" >&2
wait "$launcher"
