#!/usr/bin/env bash
# A single-node Slurm on this machine, from Debian's packages, for crom's cluster test and for
# trying `crom run SCENE --executor slurm` on one machine.
#
#   bash scripts/slurm-up.sh start [PIDFILE]  # install (first time), configure, start; wait for the node
#   bash scripts/slurm-up.sh stop [PIDFILE]   # stop the daemons that start recorded (by PID)
#
# `start` appends the PIDs of the daemons it started (none if they were running) to PIDFILE
# (default /var/lib/crom-slurm/started.pids); `stop` stops exactly those and removes the file.
# Needs root (apt-get, /etc/munge, /etc/slurm) and no systemd: the daemons are started
# directly. The node is declared with CROM_SLURM_CPUS task slots (default 4, more than the
# machine's cores if need be: `SlurmdParameters=config_overrides`), so that an array runs that
# many tasks at once. Exit 0 when `sinfo` shows the node idle; non-zero with a reason otherwise.
set -euo pipefail
STATE=${CROM_SLURM_STATE:-/var/lib/crom-slurm}
PIDS=${2:-$STATE/started.pids}
CPUS=${CROM_SLURM_CPUS:-4}

stop() {
  [ -f "$PIDS" ] || { echo "slurm-up: nothing to stop"; return 0; }
  while read -r pid name; do
    if kill "$pid" 2>/dev/null; then
      for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
      echo "slurm-up: stopped $name ($pid)"
    fi
  done <"$PIDS"
  rm -f "$PIDS"
}

start() {
  [ "$(id -u)" -eq 0 ] || { echo "slurm-up: needs root (apt-get, /etc/munge, /etc/slurm)" >&2; exit 3; }
  if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v sbatch >/dev/null \
    || ! command -v munged >/dev/null; then
    echo "slurm-up: installing munge, slurmctld, slurmd, slurm-client (Debian)"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
      munge slurmctld slurmd slurm-client >/dev/null
  fi
  mkdir -p "$STATE" /var/spool/slurmctld /var/spool/slurmd /var/log/slurm /run/munge /etc/slurm
  : >>"$PIDS"

  # munge: a 1 KiB random key owned by munge, mode 400.
  if [ ! -s /etc/munge/munge.key ]; then
    dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
  fi
  chown munge:munge /etc/munge/munge.key /run/munge 2>/dev/null || true
  chmod 400 /etc/munge/munge.key
  if ! pgrep -x munged >/dev/null; then
    rm -f /run/munge/munged.pid
    munged --force
    # munged forks into the background: its PID is the one it writes.
    for _ in $(seq 50); do [ -s /run/munge/munged.pid ] && break; sleep 0.1; done
    echo "$(cat /run/munge/munged.pid) munged" >>"$PIDS"
  fi

  host=$(hostname -s)
  conf=/etc/slurm/slurm.conf
  cat >"$conf.crom" <<EOF
# Written by crom's scripts/slurm-up.sh: a single-node cluster on $host.
ClusterName=crom
SlurmctldHost=$host
AuthType=auth/munge
SlurmUser=root
SlurmdUser=root
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=/run/slurmctld.pid
SlurmdPidFile=/run/slurmd.pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SlurmdParameters=config_overrides
ReturnToService=2
MpiDefault=none
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
KillWait=5
MinJobAge=300
NodeName=$host CPUs=$CPUS State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
  if ! cmp -s "$conf.crom" "$conf"; then
    mv "$conf.crom" "$conf"
    # A changed configuration needs fresh daemons.
    pkill -x slurmctld 2>/dev/null || true
    pkill -x slurmd 2>/dev/null || true
    sleep 1
  else
    rm -f "$conf.crom"
  fi
  if ! pgrep -x slurmctld >/dev/null; then
    slurmctld
    for _ in $(seq 50); do [ -s /run/slurmctld.pid ] && break; sleep 0.1; done
    echo "$(cat /run/slurmctld.pid) slurmctld" >>"$PIDS"
  fi
  if ! pgrep -x slurmd >/dev/null; then
    slurmd
    for _ in $(seq 50); do [ -s /run/slurmd.pid ] && break; sleep 0.1; done
    echo "$(cat /run/slurmd.pid) slurmd" >>"$PIDS"
  fi
  for _ in $(seq 60); do
    state=$(sinfo -h -n "$host" -o %T 2>/dev/null | head -1 || true)
    case "$state" in
      idle|mixed|allocated) echo "slurm-up: node $host $state, $CPUS task slots"; return 0 ;;
      down*|drain*) scontrol update nodename="$host" state=resume 2>/dev/null || true ;;
    esac
    sleep 0.5
  done
  echo "slurm-up: the node did not come up (sinfo: ${state:-nothing}); see /var/log/slurm/" >&2
  exit 1
}

case "${1:-start}" in
  start) start ;;
  stop) stop ;;
  *) echo "usage: $0 start|stop" >&2; exit 2 ;;
esac
