#!/usr/bin/env bash
# Starts a single-node Slurm cluster (Debian's slurm-wlm: slurmctld, slurmd, munge) whose state,
# logs and configuration live under the folder given, for tests/slurm.rs; prints the path of its
# slurm.conf (clients find it through SLURM_CONF). Needs root (slurmd starts jobs as their user).
# The Slurm daemons are (re)started each time, on this configuration.
set -euo pipefail
dir="$(realpath -m "$1")"
mkdir -p "$dir/state" "$dir/spool" "$dir/munge" "$dir/run"
host="$(hostname -s)"
conf="$dir/slurm.conf"
cpus="$(nproc)"
# the node's memory in MB, less a margin (a job's --mem must fit it)
memory="$(awk '/MemTotal/ { print int($2 / 1024 * 0.9) }' /proc/meminfo)"
cat > "$conf" <<CONF
ClusterName=shellbake-test
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
NodeName=$host CPUs=$cpus RealMemory=$memory State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$conf"
{
  if ! pgrep -x munged >/dev/null; then
    [ -f /etc/munge/munge.key ] || mungekey --create --keyfile /etc/munge/munge.key >/dev/null 2>&1 \
      || mungekey -c -k /etc/munge/munge.key
    chown munge:munge /etc/munge/munge.key 2>/dev/null || true
    chmod 0400 /etc/munge/munge.key
    mkdir -p /run/munge && chown munge:munge /run/munge 2>/dev/null || true
    (su -s /bin/sh munge -c munged 2>/dev/null) || munged --force
  fi
  pkill -x slurmctld 2>/dev/null || true
  pkill -x slurmd 2>/dev/null || true
  sleep 0.5
  slurmctld -f "$conf" -c
  slurmd -f "$conf"
  for _ in $(seq 1 60); do
    sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)' && break
    sleep 0.5
  done
  sinfo -h -o %t | grep -qE '^(idle|mix|alloc)' || {
    echo "slurm did not come up:" >&2; tail -20 "$dir/slurmctld.log" "$dir/slurmd.log" >&2; exit 1; }
}
echo "$conf"
