#!/usr/bin/env bash
# A one-node SLURM cluster on this machine (Debian's slurm-wlm + munge), for trying
# `sigmarl sweep hydra/launcher=slurm` without a real cluster. Run as root.
#   apt-get install -y slurm-wlm munge        # once
#   scripts/slurm_local.sh start              # then: export SLURM_CONF=/tmp/sigmarl-slurm/slurm.conf
#   scripts/slurm_local.sh stop
# Everything lives in $SLURM_LOCAL_DIR (default /tmp/sigmarl-slurm); no accounting database
# (sacct is not available; submitit falls back to squeue and the job's result files).
set -euo pipefail
DIR=${SLURM_LOCAL_DIR:-/tmp/sigmarl-slurm}
HOST=$(hostname -s)

start() {
  mkdir -p "$DIR/state" "$DIR/spool" "$DIR/munge" /run/munge
  if [ ! -S "$DIR/munge/munge.socket" ]; then
    [ -f /etc/munge/munge.key ] || /usr/sbin/mungekey --create
    /usr/sbin/munged --force --socket="$DIR/munge/munge.socket" \
      --pid-file="$DIR/munge/munged.pid" --log-file="$DIR/munge/munged.log" --seed-file="$DIR/munge/seed"
  fi
  local mem
  mem=$(awk '/MemTotal/ {print int($2 / 1024 * 0.9)}' /proc/meminfo)
  cat > "$DIR/slurm.conf" <<CONF
ClusterName=sigmarl-local
SlurmctldHost=$HOST
SlurmUser=root
AuthType=auth/munge
AuthInfo=socket=$DIR/munge/munge.socket
CredType=cred/munge
StateSaveLocation=$DIR/state
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/slurmctld.pid
SlurmdPidFile=$DIR/slurmd.pid
SlurmctldLogFile=$DIR/slurmctld.log
SlurmdLogFile=$DIR/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU_Memory
SchedulerType=sched/backfill
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
ReturnToService=2
MpiDefault=none
NodeName=$HOST CPUs=$(nproc) RealMemory=$mem State=UNKNOWN
PartitionName=local Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
  export SLURM_CONF="$DIR/slurm.conf"
  /usr/sbin/slurmctld -f "$SLURM_CONF"
  /usr/sbin/slurmd -f "$SLURM_CONF"
  for _ in $(seq 60); do
    if sinfo -h -o %t 2>/dev/null | grep -q idle; then
      echo "slurm up: export SLURM_CONF=$SLURM_CONF"; sinfo; return 0
    fi
    sleep 1
  done
  echo "slurm did not come up; see $DIR/*.log" >&2
  return 1
}

stop() {
  # let jobs end (cancel what is left) while the daemons still run, or their steps hang
  if [ -f "$DIR/slurm.conf" ]; then
    export SLURM_CONF="$DIR/slurm.conf"
    squeue -h -o %i 2>/dev/null | xargs -r scancel 2>/dev/null || true
    for _ in $(seq 30); do
      [ -z "$(squeue -h 2>/dev/null)" ] && break
      sleep 1
    done
  fi
  for pid in "$DIR/slurmd.pid" "$DIR/slurmctld.pid" "$DIR/munge/munged.pid"; do
    [ -f "$pid" ] && kill "$(cat "$pid")" 2>/dev/null || true
  done
}

case "${1:-}" in
  start) start ;;
  stop) stop ;;
  *) echo "usage: $0 start|stop" >&2; exit 2 ;;
esac
