#!/usr/bin/env bash
# A single-node SLURM on this Debian machine, for tests/slurm and trying the workflow on a cluster
# executor (docs/cluster.md). Root, no systemd: the daemons are started by hand.
#   scripts/slurm-local.sh start    install the packages if missing, and the cluster extra
#                                   (environment-slurm.txt: Snakemake's SLURM executor) into
#                                   .venv if missing; write slurm.conf, start munged, slurmctld,
#                                   slurmd; wait until the node is idle
#   scripts/slurm-local.sh status   daemons and sinfo; exit 0 only if the node takes jobs
#   scripts/slurm-local.sh stop     cancel jobs, stop the daemons it starts, remove their pid files
# Idempotent. No accounting (no slurmdbd): the workflow uses snakemake-executor-plugin-slurm 2.8,
# which reads job states from squeue (--slurm-status-command squeue). Refuses to touch a
# slurm.conf it did not write, so it never reconfigures a real cluster node.
set -euo pipefail

CONF=/etc/slurm/slurm.conf
MARK="# written by scripts/slurm-local.sh"
LOGDIR=/var/log/slurm
CTLD_LOG=$LOGDIR/slurmctld.log
SLURMD_LOG=$LOGDIR/slurmd.log
APT_LOG=$LOGDIR/slurm-local-apt.log
CTLD_PID=/run/slurmctld.pid
SLURMD_PID=/run/slurmd.pid
MUNGE_PID=/run/munge/munged.pid
PACKAGES=(slurmctld slurmd slurm-client munge)
WAIT_S=${SLURM_LOCAL_WAIT_S:-60}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
VENV_PY=$ROOT/.venv/bin/python
EXTRA=$ROOT/environment-slurm.txt

die() {
  echo "slurm-local: $*" >&2
  exit 1
}

alive() { # pid file → its process is running
  [ -s "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null
}

node_state() {
  sinfo -h -N -n "$(hostname -s)" -o %t 2>/dev/null | head -1
}

install_packages() {
  local missing=() p
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return
  command -v apt-get >/dev/null || die "missing ${missing[*]} and no apt-get (Debian only)"
  mkdir -p "$LOGDIR"
  echo "slurm-local: installing ${missing[*]} (log: $APT_LOG)"
  # Debian's maintainer scripts would start the daemons with the package's default settings;
  # policy-rc.d exit 101 forbids that (container images ship one; add it only for the install)
  local policy=""
  if [ ! -e /usr/sbin/policy-rc.d ]; then
    policy=/usr/sbin/policy-rc.d
    printf '#!/bin/sh\nexit 101\n' > "$policy"
    chmod +x "$policy"
  fi
  local ok=0
  apt-get update -q > "$APT_LOG" 2>&1 &&
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${missing[@]}" >> "$APT_LOG" 2>&1 ||
    ok=$?
  [ -n "$policy" ] && rm -f "$policy"
  [ "$ok" -eq 0 ] || die "apt-get install ${missing[*]} failed (exit $ok); see $APT_LOG"
}

plugin_pinned() { # every pin of the cluster extra installed in .venv at its version
  "$VENV_PY" - "$EXTRA" <<'EOF'
import sys
from importlib import metadata

for line in open(sys.argv[1], encoding="utf-8"):
    req = line.split("#")[0].strip()
    if req:
        name, pin = req.split("==")
        try:
            ok = metadata.version(name) == pin
        except metadata.PackageNotFoundError:
            ok = False
        if not ok:
            sys.exit(1)
EOF
}

install_plugin() {
  # the executor plugin is not in environment.txt: installed, it costs every Snakemake start
  # (environment-slurm.txt says why); scripts/setup.sh neither installs nor removes it
  if [ ! -x "$VENV_PY" ]; then
    echo "slurm-local: no .venv yet (bash scripts/setup.sh); the SLURM executor plugin is not installed"
    return
  fi
  plugin_pinned && return
  echo "slurm-local: installing the SLURM executor plugin into .venv (environment-slurm.txt)"
  "$VENV_PY" -m pip install -q -r "$EXTRA" || die "pip install -r $EXTRA failed"
}

conf_is_ours() {
  if [ -f "$CONF" ] && ! head -1 "$CONF" | grep -qF "$MARK"; then
    die "$CONF was not written by this script; not touching it (move it away to use this script)"
  fi
}

write_conf() {
  local host cpus mem hw
  host=$(hostname -s)
  # what slurmd itself detects, so the node is never drained for claiming more than it has
  hw=$(slurmd -C | head -1) || die "slurmd -C failed"
  cpus=$(sed -n 's/.* CPUs=\([0-9]*\).*/\1/p' <<< "$hw")
  mem=$(sed -n 's/.* RealMemory=\([0-9]*\).*/\1/p' <<< "$hw")
  if [ -z "$cpus" ] || [ -z "$mem" ] || [ "$cpus" -eq 0 ]; then
    die "cannot read CPUs/RealMemory from 'slurmd -C': $hw"
  fi
  mkdir -p /etc/slurm
  cat > "$CONF" <<EOF
$MARK ($(date -u +%FT%TZ)); regenerated at every start
ClusterName=local
SlurmctldHost=$host
SlurmUser=slurm
AuthType=auth/munge
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=$CTLD_PID
SlurmdPidFile=$SLURMD_PID
SlurmctldLogFile=$CTLD_LOG
SlurmdLogFile=$SLURMD_LOG
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
# Without a default, a job submitted without --mem (the Snakemake plugin sends none unless
# mem_mb is set) is given the whole node's memory, and jobs then run one at a time.
DefMemPerCPU=$((mem / cpus))
# No accounting: Snakemake's SLURM plugin reads job states from squeue, which shows a finished
# job for MinJobAge seconds (300 is SLURM's default; the plugin wants >= 3 status-check intervals)
MinJobAge=300
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
ReturnToService=2
SchedulerType=sched/backfill
MpiDefault=none
NodeName=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
}

start_munge() {
  if munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
    return
  fi
  [ -s /etc/munge/munge.key ] || mungekey --create >/dev/null || die "cannot create the munge key"
  mkdir -p /run/munge
  chown munge:munge /run/munge
  runuser -u munge -- /usr/sbin/munged || die "munged did not start; see /var/log/munge/munged.log"
  local i
  for i in $(seq 50); do
    munge -n 2>/dev/null | unmunge >/dev/null 2>&1 && return
    sleep 0.1
  done
  die "munge does not answer; see /var/log/munge/munged.log"
}

start() {
  [ "$(id -u)" -eq 0 ] || die "must run as root (installs packages, starts daemons)"
  install_packages
  install_plugin
  if alive "$CTLD_PID" && alive "$SLURMD_PID"; then
    case $(node_state) in
      idle | mix | alloc)
        echo "slurm-local: already running"
        sinfo
        return
        ;;
    esac
  fi
  alive "$CTLD_PID" || conf_is_ours
  mkdir -p /var/spool/slurmctld /var/spool/slurmd "$LOGDIR"
  chown slurm:slurm /var/spool/slurmctld "$LOGDIR"
  start_munge
  if ! alive "$CTLD_PID"; then
    write_conf
    # -c: forget jobs and node states from an earlier run (a test cluster starts empty)
    /usr/sbin/slurmctld -c || die "slurmctld did not start; see $CTLD_LOG"
  fi
  if ! alive "$SLURMD_PID"; then
    /usr/sbin/slurmd || die "slurmd did not start; see $SLURMD_LOG"
  fi
  local i state=""
  for i in $(seq "$WAIT_S"); do
    state=$(node_state)
    case $state in
      idle | mix | alloc)
        echo "slurm-local: node $(hostname -s) $state after ${i} s"
        sinfo
        return
        ;;
    esac
    sleep 1
  done
  die "node $(hostname -s) not idle after $WAIT_S s (state: ${state:-none}); see $CTLD_LOG and $SLURMD_LOG"
}

stop_pid() { # pid file, name: TERM, wait up to 10 s, then KILL
  alive "$1" || {
    rm -f "$1"
    return
  }
  local pid i
  pid=$(cat "$1")
  kill "$pid"
  for i in $(seq 100); do
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.1
  done
  if kill -0 "$pid" 2>/dev/null; then
    echo "slurm-local: $2 ($pid) ignored SIGTERM for 10 s; killing it" >&2
    kill -9 "$pid" 2>/dev/null || true
  fi
  rm -f "$1"
}

stop() {
  [ "$(id -u)" -eq 0 ] || die "must run as root"
  if alive "$CTLD_PID"; then
    # running jobs would leave their slurmstepd behind once slurmd is gone
    scancel --partition=debug 2>/dev/null || true
    local i
    for i in $(seq 20); do
      [ -z "$(squeue -h -o %i 2>/dev/null)" ] && break
      sleep 0.5
    done
  fi
  stop_pid "$SLURMD_PID" slurmd
  stop_pid "$CTLD_PID" slurmctld
  stop_pid "$MUNGE_PID" munged
  echo "slurm-local: stopped"
}

status() {
  local ok=0 d
  for d in "munged:$MUNGE_PID" "slurmctld:$CTLD_PID" "slurmd:$SLURMD_PID"; do
    if alive "${d#*:}"; then
      echo "${d%%:*}: running (pid $(cat "${d#*:}"))"
    else
      echo "${d%%:*}: not running"
      ok=1
    fi
  done
  if [ $ok -eq 0 ]; then
    sinfo
    case $(node_state) in idle | mix | alloc) ;; *) ok=1 ;; esac
  fi
  return $ok
}

case ${1:-} in
  start) start ;;
  stop) stop ;;
  status) status ;;
  *) die "usage: $0 start|stop|status" ;;
esac
