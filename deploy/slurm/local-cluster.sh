#!/usr/bin/env bash
# A real single-node Slurm cluster on this machine, for trying and testing the scripts beside
# this one: munged, slurmctld and slurmd, started by hand (no systemd), with every file in
# one directory and ports of their own, so nothing of a system Slurm is touched.
#
#   usage: deploy/slurm/local-cluster.sh start|stop|status
#
#   start   installs Debian's slurm-wlm and munge with apt-get when missing (needs root),
#           writes the configuration (the node line from `slurmd -C`), starts the daemons,
#           waits until the node takes jobs, and prints the line that points Slurm's
#           commands at it:  eval "$(deploy/slurm/local-cluster.sh start)"
#           (one that fails, or is interrupted, half-way stops what it started)
#   stop    cancels every job and stops every process it started (the logs stay)
#   status  says whether the cluster runs, and prints the same line
#
#   TESSERA_SLURM_DIR   where it lives (default /tmp/tessera-slurm)
#   TESSERA_SLURM_PORT  slurmctld's port; slurmd takes the next (default 16817)
#
# The daemons run as root, which slurmd needs and Slurm's own user would otherwise be.
set -euo pipefail
dir=${TESSERA_SLURM_DIR:-/tmp/tessera-slurm}
port=${TESSERA_SLURM_PORT:-16817}
conf=$dir/slurm.conf
export SLURM_CONF=$conf
# What every cluster directory this script makes holds from its first moment.
mark=.tessera-local-cluster
# The first line of every slurm.conf this script writes, the mark's before there was one.
header="# Written by deploy/slurm/local-cluster.sh: a single-node cluster for tests."

say() { echo "local-cluster: $*" >&2; }
fail() {
  say "$*"
  exit 1
}

# The pid in pid file $1 if that process runs and is root's daemon $2. A daemon that ended
# without `stop` (slurmctld finding its port taken, a crash, a reboot) leaves its pid file,
# and the pid is soon another process's (of 32768 pids, on many machines): `stop` sent TERM
# and KILL to whatever had it, another user's process included, and `start` took two such
# processes for a running cluster.
running_pid() {
  local pid
  [ -f "$1" ] && pid=$(cat "$1") && [[ $pid =~ ^[1-9][0-9]{0,9}$ ]] &&
    [ "$(cat "/proc/$pid/comm" 2>/dev/null)" = "$2" ] &&
    [ "$(stat -c %u "/proc/$pid" 2>/dev/null)" = 0 ] && echo "$pid"
}

# Refuses the directory $1 above the cluster's where another user owns it or may write it
# (unless it is sticky, as /tmp is): they could rename the cluster's directory away.
trust_above() {
  local owner mode
  owner=$(stat -c %u -- "$1")
  [ "$owner" = 0 ] || [ "$owner" = "$(id -u)" ] ||
    fail "$1, above $dir, belongs to another user (uid $owner), who could put their own directory in its place: choose a TESSERA_SLURM_DIR whose parents are root's"
  mode=$(stat -c %a -- "$1")
  [ $((8#$mode & 8#022)) = 0 ] || [ $((8#$mode & 8#1000)) != 0 ] ||
    fail "$1, above $dir, may be written by other users (mode $mode), who could put their own directory in its place: choose a TESSERA_SLURM_DIR whose parents are root's"
}

# Each directory above the cluster's as TESSERA_SLURM_DIR names it, from / down, is held to
# the same rule, and a link among them must be root's or this user's: another user's link
# (in a sticky /tmp) is theirs to point elsewhere whenever they like, so the physical path
# found through it says nothing of the next command's, and root's `start` removed whatever
# directory of that name it led to.
check_given() {
  local abs p part owner parts
  case $dir in
  /*) abs=$dir ;;
  *) abs=$PWD/$dir ;;
  esac
  IFS=/ read -ra parts <<<"$(dirname -- "$abs")"
  p=
  for part in "${parts[@]}"; do
    [ -n "$part" ] || continue
    p=$p/$part
    if [ -L "$p" ]; then
      owner=$(stat -c %u -- "$p")
      [ "$owner" = 0 ] || [ "$owner" = "$(id -u)" ] ||
        fail "$p, above $dir, is a link of another user's (uid $owner), who could point it elsewhere: choose a TESSERA_SLURM_DIR whose parents are root's"
    elif [ -d "$p" ]; then
      trust_above "$p"
    else
      return 0
    fi
  done
}

# Each directory above the cluster's, from its physical path up to /, must be this user's or
# root's, and not writable by other users unless sticky (as /tmp is): one that another user
# owns or may write lets them rename the cluster's directory away, even after the checks
# below, and put their own in its place, whose slurm.conf root's sinfo and sbatch then read
# and load plugins from. The cluster's directory is then named by that physical path, so a
# link on the way cannot be pointed elsewhere later either, and `resolved` says so.
#
# A parent not made yet is checked from the nearest directory above it that exists, and the
# cluster's directory is left unresolved: nothing runs there, and nothing at that path is
# read or removed, since another user may make the missing parents (in a sticky /tmp) after
# this check, with a link among them to any directory of root's. `start` once removed
# whatever such a link led to (`rm -rf`) while apt-get installed Slurm.
resolved=
check_parents() {
  local parent p
  check_given
  parent=$(dirname -- "$dir")
  p=$parent
  while [ ! -d "$p" ]; do
    p=$(dirname -- "$p")
  done
  p=$(realpath -e -- "$p") || fail "could not resolve $(dirname -- "$dir")"
  local top=$p
  while :; do
    trust_above "$p"
    [ "$p" = / ] && break
    p=$(dirname -- "$p")
  done
  [ -d "$parent" ] || return 0
  # The parent exists now: `top` is it, physically, unless a link was made in between.
  [ "$top" = "$(realpath -e -- "$parent")" ] || fail "$parent changed while it was checked"
  dir=${top%/}/$(basename -- "$dir")
  conf=$dir/slurm.conf
  export SLURM_CONF=$conf
  resolved=1
}

# The cluster's directory must be this user's own: root trusts its pid files (which
# processes `stop` kills) and its slurm.conf (which plugins Slurm's commands load), so one
# another user made or may write, in a shared /tmp, is refused, as is a link.
check_dir() {
  check_parents
  [ -e "$dir" ] || [ -L "$dir" ] || return 0
  if [ -L "$dir" ] || [ ! -d "$dir" ]; then
    fail "$dir is not a directory (a link or another file): remove it, or set TESSERA_SLURM_DIR"
  fi
  local owner mode
  owner=$(stat -c %u -- "$dir")
  [ "$owner" = "$(id -u)" ] ||
    fail "$dir belongs to another user (uid $owner), whose pid files and slurm.conf are not trusted: remove it, or set TESSERA_SLURM_DIR"
  mode=$(stat -c %a -- "$dir")
  [ $((8#$mode & 8#022)) = 0 ] ||
    fail "$dir may be written by other users (mode $mode), whose pid files and slurm.conf are not trusted: remove it, or set TESSERA_SLURM_DIR"
  # `start` removes the directory whole and `stop` ends the processes its pid files name, so
  # only one this script made (its mark inside) or an empty one is taken: any other of
  # root's was removed (TESSERA_SLURM_DIR=/var/lib), or had the system's own daemons stopped
  # (=/run, where Debian's munged and slurmd keep their pid files).
  # A directory an earlier version of this script made, before the mark, is known by the
  # first line of its slurm.conf: nobody but this user writes there (checked above).
  if [ ! -f "$dir/$mark" ] && [ -n "$(ls -A -- "$dir")" ] &&
    ! { [ -f "$conf" ] && [ ! -L "$conf" ] && [ "$(head -n 1 -- "$conf")" = "$header" ]; }; then
    fail "$dir is not a cluster this script made (it has no $mark), so it is neither removed nor stopped: set TESSERA_SLURM_DIR to a new or an empty directory"
  fi
}

# TESSERA_SLURM_PORT goes into slurm.conf and arithmetic: a decimal port, and the next one
# free for slurmd, or nothing starts.
check_port() {
  case $port in
  '' | *[!0-9]* | ??????*) fail "TESSERA_SLURM_PORT=$port is not a port from 1 to 65534" ;;
  esac
  [ $((10#$port)) -ge 1 ] && [ $((10#$port)) -le 65534 ] ||
    fail "TESSERA_SLURM_PORT=$port is not a port from 1 to 65534"
  port=$((10#$port))
}

# The socket listening on TCP port $1 on any address, as "inode uid" lines (/proc/net/tcp
# and tcp6; state 0A is LISTEN), read without awk, which a bare PATH may lack.
listeners() {
  local hex file _sl addr st uid inode _rest
  hex=$(printf '%04X' "$1")
  for file in /proc/net/tcp /proc/net/tcp6; do
    [ -r "$file" ] || continue
    while read -r _sl addr _rest st _rest _rest _rest uid _rest inode _rest; do
      [ "$st" = 0A ] && [ "${addr##*:}" = "$hex" ] && echo "$inode $uid"
    done <"$file"
  done
  return 0
}

# slurmctld and slurmd take their ports only once started in the background, and one that
# finds its port taken ends there; Slurm's commands then talk to whatever holds the port.
# Another user's listener on 127.0.0.1 was sent root's sinfo requests (credentials of
# root's, which root's slurmd takes as root's for five minutes) and the node's
# registrations while `start` waited (minutes, not the 30 s it said). So a port taken
# before anything starts is refused, and after the daemons start, each must hold its own.
check_ports_free() {
  local p taken
  for p in "$port" $((port + 1)); do
    taken=$(listeners "$p")
    [ -z "$taken" ] ||
      fail "port $p is already taken on this machine (by uid ${taken##* }), and Slurm's commands would talk to whoever holds it: set TESSERA_SLURM_PORT to a free port (slurmd takes the next)"
  done
}

# Waits up to 10 s until the daemon in pid file $1 ($3) listens on port $2 itself, and fails
# where it ended, or where another process holds the port.
held_by() {
  local pid inode uid fd i found
  for i in $(seq 1 50); do
    # A daemon writes its pid file once in the background, after its command has returned:
    # none yet is a daemon still starting, one naming no daemon is one that has ended.
    if ! pid=$(running_pid "$1" "$3"); then
      [ ! -s "$1" ] || fail "$3 ended as it started (is port $2 taken?); see $dir/log/$3.log"
      sleep 0.2
      continue
    fi
    found=
    while read -r inode uid; do
      [ -n "$inode" ] || continue
      for fd in /proc/"$pid"/fd/*; do
        [ "$(readlink -- "$fd" 2>/dev/null)" = "socket:[$inode]" ] && found=1 && continue 2
      done
      fail "port $2 is held by another process (uid $uid), not $3: set TESSERA_SLURM_PORT to a free port (slurmd takes the next)"
    done <<<"$(listeners "$2")"
    [ -n "$found" ] && return 0
    sleep 0.2
  done
  fail "$3 did not listen on port $2 within 10 s; see $dir/log/$3.log"
}

# slurm.conf and munged's options take the directory's paths unquoted: a space or `#` ends
# a value there, `%` is expanded, `,` splits AuthInfo's fields, so such a name failed only
# once munged ran. Anything but letters, digits and `/._+-` is refused before anything
# starts, which also keeps the line `start` prints for eval one word.
check_name() {
  case $dir in
  *[!A-Za-z0-9/._+-]*)
    fail "$dir holds a character slurm.conf cannot take (only letters, digits and /._+- may name the directory): set TESSERA_SLURM_DIR"
    ;;
  esac
}

# Whether the cluster runs: never where its directory's parent does not exist (`resolved`).
is_up() {
  [ -n "$resolved" ] &&
    running_pid "$dir/slurmctld.pid" slurmctld >/dev/null &&
    running_pid "$dir/slurmd.pid" slurmd >/dev/null
}

install_packages() {
  local tool missing=
  for tool in munged slurmctld slurmd sbatch; do
    command -v "$tool" >/dev/null || missing=1
  done
  [ -z "$missing" ] && return 0
  [ "$(id -u)" = 0 ] || fail "Slurm is not installed and installing it needs root (apt-get install slurm-wlm munge)"
  command -v apt-get >/dev/null || fail "Slurm is not installed and there is no apt-get to install it"
  say "installing slurm-wlm and munge"
  apt-get update -qq >&2
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge >&2
}

write_config() {
  local host node
  host=$(hostname -s)
  # slurmd -C prints this machine's node line (CPUs, sockets, cores, memory) and an uptime.
  node=$(slurmd -C | grep '^NodeName=')
  [ -n "$node" ] || fail "slurmd -C printed no node line"
  cat >"$conf" <<EOF
$header
ClusterName=tessera-local
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge/munge.socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
# Start batch jobs at once rather than up to 3 s later: tests wait on many short jobs.
SchedulerParameters=batch_sched_delay=0
MpiDefault=none
# Every daemon listens on the address its host line names (127.0.0.1), not on every address
# of the machine, which is Slurm's default: the cluster is for this machine alone.
CommunicationParameters=NoCtldInAddrAny,NoInAddrAny
SwitchType=switch/none
ReturnToService=2
JobCompType=jobcomp/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
$node NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=local Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
}

start() {
  [ "$(id -u)" = 0 ] || fail "starting the daemons needs root (slurmd runs jobs as their users)"
  if is_up; then
    say "already running in $dir"
    echo "export SLURM_CONF=$conf"
    return 0
  fi
  check_name
  check_port
  install_packages
  check_ports_free
  # Only a path resolved through directories no other user may change is removed: where the
  # parent did not exist, nothing is there of an earlier cluster's.
  [ -z "$resolved" ] || rm -rf -- "$dir"
  # Made afresh, not taken over: another user's directory made since the line above fails.
  mkdir -p -- "$(dirname -- "$dir")"
  # Checked again now that every parent exists: another user may have made a missing one.
  check_parents
  check_name
  mkdir -m 755 -- "$dir" || fail "could not make $dir afresh"
  echo "A single-node Slurm cluster made by deploy/slurm/local-cluster.sh" >"$dir/$mark"
  mkdir -- "$dir/munge" "$dir/state" "$dir/spool" "$dir/log"
  # munged insists on a private key and a socket directory others may enter.
  chmod 755 "$dir/munge"
  (umask 077 && head -c 1024 /dev/urandom >"$dir/munge/munge.key")
  chmod 400 "$dir/munge/munge.key"
  # From here a start that fails or is interrupted half-way (slurmd cannot start, Ctrl-C
  # while waiting for the node) stops what it started rather than leave root's daemons
  # running with nothing to say so.
  trap 'stop >/dev/null 2>&1 || true' EXIT
  trap 'exit 130' INT TERM
  munged --force --key-file="$dir/munge/munge.key" --socket="$dir/munge/munge.socket" \
    --pid-file="$dir/munge/munged.pid" --log-file="$dir/log/munged.log" \
    --seed-file="$dir/munge/munged.seed" ||
    fail "munged did not start; see $dir/log/munged.log"
  write_config
  # Each daemon holds its own port before anything talks to it: slurmd starts only once
  # slurmctld listens, or it registers (root's credentials) with whoever took slurmctld's
  # port between the check above and slurmctld's start.
  slurmctld -f "$conf" || fail "slurmctld did not start; see $dir/log/slurmctld.log"
  held_by "$dir/slurmctld.pid" "$port" slurmctld
  slurmd -f "$conf" || fail "slurmd did not start; see $dir/log/slurmd.log"
  held_by "$dir/slurmd.pid" $((port + 1)) slurmd
  # 30 s by the clock: each sinfo may wait out Slurm's message timeout (10 s) on a daemon
  # that does not answer, so 60 tries of it took minutes; each try is cut at 5 s.
  local deadline=$((SECONDS + 30))
  until [ "$(timeout 5 sinfo -h -o %t 2>/dev/null)" = idle ]; do
    if [ $SECONDS -ge $deadline ]; then
      tail -n 20 "$dir"/log/*.log >&2 || true
      fail "the node did not become idle within 30 s"
    fi
    sleep 0.5
  done
  trap - EXIT INT TERM
  say "running in $dir: $(sinfo -h -N -o '%N, %c CPUs, %m MB')"
  echo "export SLURM_CONF=$conf"
}

# Sends TERM to daemon $2 in pid file $1 and waits up to 10 s for it to end, then KILL; the
# pid file, which names no daemon of the cluster's from then on, is removed.
end_process() {
  local pid i
  pid=$(running_pid "$1" "$2") || {
    rm -f -- "$1"
    return 0
  }
  kill "$pid" 2>/dev/null || true
  for i in $(seq 1 50); do
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.2
  done
  kill -0 "$pid" 2>/dev/null && { kill -9 "$pid" 2>/dev/null || true; }
  rm -f -- "$1"
}

stop() {
  if [ -z "$resolved" ]; then
    say "not running (there is no $(dirname -- "$dir"))"
    return 0
  fi
  if [ -f "$conf" ] && is_up; then
    # Jobs first, so no job step outlives the daemons.
    squeue -h -o %A 2>/dev/null | sort -u | xargs -r scancel --quiet 2>/dev/null || true
    local i
    for i in $(seq 1 50); do
      [ -z "$(squeue -h -o %A 2>/dev/null)" ] && break
      sleep 0.2
    done
  fi
  end_process "$dir/slurmd.pid" slurmd
  end_process "$dir/slurmctld.pid" slurmctld
  end_process "$dir/munge/munged.pid" munged
  # The logs stay for a look after a failure; the next start begins afresh.
  rm -rf "$dir/state" "$dir/spool"
  say "stopped"
}

status() {
  if is_up; then
    say "running in $dir: $(sinfo -h -N -o '%N %t, %c CPUs')"
    echo "export SLURM_CONF=$conf"
  else
    say "not running"
    return 1
  fi
}

case "${1:-}" in
start | stop | status) check_dir ;;
esac
case "${1:-}" in
start) start ;;
stop) stop ;;
status) status ;;
*) fail "usage: $0 start|stop|status" ;;
esac
