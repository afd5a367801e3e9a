#!/usr/bin/env bash
# `make test-farm`: `retrace farm` on a real single-node Slurm that this
# script starts by hand (munged, slurmctld, slurmd; no systemd) in a
# private temporary folder, on free ports, and stops again by PID on exit.
#
#   1. The bouncing ball (--spp 16, 3 chunks) and E4 (320x240, 4 chunks)
#      are submitted with `retrace farm submit`; while the ball's task 1
#      renders, it is cancelled (scancel): it must stop, leave no partial
#      file, and resume when requeued. Every frame of both runs must
#      decode to the same pixels as one local long run of the scene, and
#      E4's assembly job must write the GIF, merged statistics and report.
#   2. The ball again, 3 chunks, with chunk 1's statistics file made
#      unwritable (a folder in its place): `farm status` must name the task
#      with its exit code, and the assembly job must not run.
#   3. A task cancelled and requeued with `retrace farm requeue` within
#      the same second, with a scheduling pass in that second: it must run
#      again and complete (slurmd refuses a launch that early).
#
# Usage: farm/test-farm.sh [RETRACE]   (default target/release/retrace)
# Needs root (munged runs as user munge, the jobs as root) and the Debian
# packages slurmctld slurmd slurm-client munge (`make farm-deps`).
set -Eeuo pipefail
umask 022
cd "$(dirname "$0")/.."
retrace=$(readlink -f "${1:-target/release/retrace}")
[[ -x $retrace ]] || { echo "test-farm: no binary at $retrace (make build)" >&2; exit 2; }
[[ $(id -u) == 0 ]] || { echo "test-farm: run as root (the daemons need it)" >&2; exit 2; }
started=$SECONDS

base=$(mktemp -d /tmp/retrace-farm.XXXXXX)
# munged (user munge) must reach its socket folder inside.
chmod 755 "$base"
etc=$base/etc state=$base/state logs=$base/log run=$base/run munge=$base/munge work=$base/work
mkdir -p "$etc" "$state/ctld" "$state/slurmd" "$logs" "$run" "$munge" "$work"
export SLURM_CONF=$etc/slurm.conf
socket=$munge/munge.socket.2
node=$(hostname -s)

log() { printf '[test-farm %4ds] %s\n' $((SECONDS - started)) "$*" >&2; }
fail() {
  log "FAILED: $*"
  exit 1
}

# Alive and not a zombie (PID 1 here reaps late, so a stopped daemon
# lingers as a zombie for a while).
alive() {
  [[ -r /proc/$1/stat ]] && [[ $(awk '{print $3}' "/proc/$1/stat" 2>/dev/null) != Z ]]
}
pid_of() { [[ -s $1 ]] && tr -dc 0-9 <"$1"; }
stop() { # NAME PIDFILE
  local pid i
  pid=$(pid_of "$2") || return 0
  alive "$pid" || return 0
  kill -TERM "$pid" 2>/dev/null || return 0
  for ((i = 0; i < 100; i++)); do alive "$pid" || return 0; sleep 0.2; done
  log "$1 ($pid) did not stop on SIGTERM: SIGKILL"
  kill -KILL "$pid" 2>/dev/null || true
}
cleanup() {
  local status=$?
  trap - EXIT
  if [[ -n $(pid_of "$run/slurmctld.pid") ]] && alive "$(pid_of "$run/slurmctld.pid")"; then
    local jobs
    jobs=$(squeue -h -o %A 2>/dev/null | sort -u | tr '\n' ' ') || jobs=
    if [[ -n ${jobs// /} ]]; then
      scancel $jobs 2>/dev/null || true
      for ((i = 0; i < 60; i++)); do [[ -z $(squeue -h -o %i 2>/dev/null) ]] && break; sleep 0.5; done
    fi
  fi
  stop slurmd "$run/slurmd.pid"
  stop slurmctld "$run/slurmctld.pid"
  stop munged "$munge/munged.pid"
  # Job step daemons, batch scripts and their retrace carry this cluster's
  # SLURM_CONF in their environment (this script does too: it is left out
  # by name); step daemons end shortly after their job.
  local left i
  for ((i = 0; i < 50; i++)); do
    left=$(grep -lzx "SLURM_CONF=$SLURM_CONF" /proc/[0-9]*/environ 2>/dev/null | cut -d/ -f3 |
      while read -r pid; do
        alive "$pid" || continue
        case $(cat "/proc/$pid/comm" 2>/dev/null) in
          slurmstepd | retrace) echo "$pid" ;;
          *) tr '\0' ' ' 2>/dev/null <"/proc/$pid/cmdline" | grep -q slurm_script && echo "$pid" ;;
        esac
      done | tr '\n' ' ') || true
    [[ -z $left ]] && break
    sleep 0.2
  done
  if [[ -n $left ]]; then
    log "processes of this cluster still running: $left"
    ((status != 0)) || status=1
  fi
  if ((status == 0)); then
    rm -rf "$base"
    log "passed in $((SECONDS - started)) s; every daemon stopped"
  else
    log "failed (status $status); daemons stopped; logs kept in $base"
  fi
  exit "$status"
}
trap cleanup EXIT

# Two free TCP ports next to each other: another Slurm may use the defaults.
port_busy() {
  local hex
  hex=$(printf ':%04X' "$1")
  awk -v p="$hex" '$4 == "0A" && substr($2, length($2) - 4) == p {f = 1} END {exit !f}' \
    /proc/net/tcp /proc/net/tcp6 2>/dev/null
}
for ((port = 20000 + RANDOM % 20000; ; port += 2)); do
  port_busy "$port" || port_busy $((port + 1)) || break
done

node_line=$(slurmd -C | grep '^NodeName=')
cat >"$SLURM_CONF" <<EOF
ClusterName=retracetest
SlurmctldHost=$node(127.0.0.1)
SlurmUser=root
SlurmctldPort=$port
SlurmdPort=$((port + 1))
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$socket
StateSaveLocation=$state/ctld
SlurmdSpoolDir=$state/slurmd
SlurmctldPidFile=$run/slurmctld.pid
SlurmdPidFile=$run/slurmd.pid
SlurmctldLogFile=$logs/slurmctld.log
SlurmdLogFile=$logs/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
MpiDefault=none
MailProg=/bin/true
AccountingStorageType=accounting_storage/none
JobRequeue=1
ReturnToService=2
KillWait=10
MinJobAge=600
$node_line NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=main Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF

wait_for() { # SECONDS WHAT COMMAND...
  local limit=$1 what=$2 i
  shift 2
  for ((i = 0; i < limit * 5; i++)); do "$@" >/dev/null 2>&1 && return 0; sleep 0.2; done
  fail "timed out after ${limit}s waiting for $what"
}
chown munge:munge "$munge"
runuser -u munge -- mungekey --create --keyfile="$munge/munge.key"
runuser -u munge -- munged --socket="$socket" --key-file="$munge/munge.key" \
  --pid-file="$munge/munged.pid" --log-file="$munge/munged.log" --seed-file="$munge/munged.seed"
wait_for 10 munged bash -c "munge -n -S '$socket' | unmunge -S '$socket'"
slurmctld -f "$SLURM_CONF"
wait_for 30 slurmctld bash -c '[[ $(scontrol ping) == *"is UP"* ]]'
slurmd -f "$SLURM_CONF"
node_idle() { [[ $(sinfo -h -n "$node" -o %T) == idle ]]; }
wait_for 60 "node $node to be idle" node_idle
log "Slurm up (ports $port-$((port + 1)), folder $base): munged $(pid_of "$munge/munged.pid"), slurmctld $(pid_of "$run/slurmctld.pid"), slurmd $(pid_of "$run/slurmd.pid")"

# --------------------------------------------------------------- helpers
# Job states one a line (tasks of an array each), from slurmctld.
states() { squeue -h -j "$1" -t all -o %T 2>/dev/null; }
cancelled() { [[ $(states "$1") == CANCELLED ]]; }
# Waits until no task of the jobs is pending, running or completing
# (polling: `sbatch --wait` polls at 2, 8 and then every 32 s, and cannot
# wait again after a requeue). A job held by a dependency that can never be
# met counts as ended.
wait_jobs() {
  local job t0=$SECONDS
  for job in "$@"; do
    while :; do
      local out reasons
      out=$(states "$job")
      reasons=$(squeue -h -j "$job" -t all -o %r 2>/dev/null)
      if ! grep -qE 'PENDING|RUNNING|COMPLETING|CONFIGURING|REQUEUE|SUSPENDED' <<<"$out"; then break; fi
      if [[ $out == PENDING && $reasons == DependencyNeverSatisfied ]]; then break; fi
      ((SECONDS - t0 < 300)) || fail "job $job not done after 300 s: $(tr '\n' ' ' <<<"$out")"
      sleep 1
    done
  done
}
# submit OUTVAR ARGS...: `retrace farm submit ARGS`; sets OUTVAR to
# "ARRAY ASSEMBLY".
submit() {
  local var=$1 text array assembly
  shift
  text=$("$retrace" farm submit "$@") || fail "farm submit $*"
  array=$(awk '/^render array job:/ {print $4}' <<<"$text")
  assembly=$(awk '/^assembly job:/ {print $3}' <<<"$text")
  [[ -n $array && -n $assembly ]] || fail "farm submit printed no job ids: $text"
  printf -v "$var" '%s %s' "$array" "$assembly"
}
# Same frame files, decoding to the same pixels.
same_frames() { # REFERENCE_DIR DIR COUNT
  /usr/bin/python3 - "$@" <<'EOF'
import os, sys
from PIL import Image
ref, out, count = sys.argv[1], sys.argv[2], int(sys.argv[3])
frames = sorted(f for f in os.listdir(ref) if f.endswith(".png"))
mine = sorted(f for f in os.listdir(out) if f.startswith("frame_") and f.endswith(".png"))
if len(frames) != count or frames != mine:
    sys.exit(f"{out}: {len(mine)} frame files, the reference has {len(frames)} (want {count})")
for name in frames:
    a, b = Image.open(os.path.join(ref, name)), Image.open(os.path.join(out, name))
    if a.size != b.size or a.mode != b.mode or a.tobytes() != b.tobytes():
        sys.exit(f"{out}/{name}: pixels differ from the long run's")
print(f"{count} frames decode to the long run's pixels: {out}")
EOF
}
# No temporary (unfinished) file anywhere in DIR left by a process that
# has ended. A task still running (the cancelled task's neighbours) may be
# writing one: `.NAME.HOST-PID.N.tmp` names its writer.
no_partial_files() {
  local left="" file pid
  while IFS= read -r file; do
    pid=$(sed -nE 's/.*-([0-9]+)\.[0-9]+\.tmp$/\1/p' <<<"${file##*/}")
    [[ -n $pid && -d /proc/$pid ]] || left+="$file "
  done < <(find "$1" -name '.*.tmp' -o -name '*.tmp.*')
  [[ -z $left ]] || fail "unfinished files left in $1: $left"
}

# --------------------------------------------------------------- references
ball_spp=16
log "local long runs (the references)"
"$retrace" animate scenes/paper-bounce.toml --spp $ball_spp -o "$work/ref-ball/frame_####.png" 2>/dev/null
"$retrace" animate scenes/paper-all.toml --width 320 --height 240 -o "$work/ref-e4/frame_####.png" 2>/dev/null

# --------------------------------------------------------------- 1. farm runs, a cancel, a requeue
# The ball first: its tasks 0 and 1 take the node's two CPUs at once.
submit ball scenes/paper-bounce.toml --chunks 3 --spp $ball_spp -o "$work/ball/frame_####.png"
submit e4 scenes/paper-all.toml --chunks 4 --width 320 --height 240 -o "$work/e4/frame_####.png"
read -r ball_array ball_assembly <<<"$ball"
read -r e4_array e4_assembly <<<"$e4"
log "submitted: ball array $ball_array (assembly $ball_assembly), E4 array $e4_array (assembly $e4_assembly)"

# Chunk 1 of the ball is frames 33-65; cancel it once it is under way.
wait_for 120 "ball task 1 to write frame 35" test -e "$work/ball/frame_0035.png"
scancel "${ball_array}_1"
cancelled_at=$SECONDS
wait_for 30 "the cancelled task to end" cancelled "${ball_array}_1"
log "ball task 1 cancelled; ended within $((SECONDS - cancelled_at)) s"
task_log=$work/ball/logs/render-${ball_array}_1.log
grep -q '^interrupted' "$task_log" || fail "the cancelled task's log does not say it was interrupted: $(cat "$task_log")"
kept=$(ls "$work/ball" | grep -cE '^frame_00(3[3-9]|[45][0-9]|6[0-5])\.png$' || true)
((kept < 33)) || fail "chunk 1 was complete before the cancel reached it: nothing tested"
no_partial_files "$work/ball"
log "chunk 1 stopped with $kept of its 33 frames written, no partial file"
"$retrace" farm requeue "$ball_array" 1 --assembly "$ball_assembly" >&2
wait_jobs "$ball_array" "$e4_array" "$ball_assembly" "$e4_assembly"
"$retrace" farm status "$ball_array" "$ball_assembly" "$e4_array" "$e4_assembly" | tee "$work/status-1.txt" >&2
grep -q "Restarts=1" <(scontrol -o show job "${ball_array}_1") || fail "ball task 1 was not restarted once"
grep -q "($kept more skipped: their files exist)" "$task_log" ||
  fail "the requeued task did not resume from the $kept frames kept: $(tail -3 "$task_log")"
same_frames "$work/ref-ball" "$work/ball" 100 >&2 || fail "ball frames"
same_frames "$work/ref-e4" "$work/e4" 100 >&2 || fail "E4 frames"
no_partial_files "$work/ball"
no_partial_files "$work/e4"
[[ $(states "$e4_assembly") == COMPLETED ]] || fail "E4's assembly job: $(states "$e4_assembly")"
for f in animation.gif animation.mp4 stats.csv stats.json report.md savings.png; do
  [[ -s $work/e4/$f ]] || fail "E4's assembly wrote no $f"
done
rows=$(($(wc -l <"$work/e4/stats.csv") - 1))
((rows == 100)) || fail "E4's merged stats.csv has $rows rows, not 100"
mp4_frames=$(ffprobe -v error -count_frames -select_streams v:0 \
  -show_entries stream=nb_read_frames -of csv=p=0 "$work/e4/animation.mp4")
((mp4_frames == 100)) || fail "E4's animation.mp4 has $mp4_frames frames, not 100"
grep -q "^Restarts: " "$work/e4/report.md" || fail "E4's report.md does not say what its restarts cost"
log "E4 assembled: animation.gif, animation.mp4 (100 frames), stats.csv (100 rows), stats.json, report.md, savings.png"
[[ $(states "$ball_assembly") == COMPLETED ]] || fail "the ball's assembly job after the requeue: $(states "$ball_assembly")"
rows=$(($(wc -l <"$work/ball/stats.csv") - 1))
((rows == 100)) || fail "the ball's merged stats.csv has $rows rows, not 100 (the requeued chunk's earlier frames lost?)"
log "the ball assembled after the requeue, its stats.csv has all 100 rows"

# --------------------------------------------------------------- 2. a task that fails
mkdir -p "$work/fail/stats.chunk1.json"
submit fail scenes/paper-bounce.toml --chunks 3 -o "$work/fail/frame_####.png"
read -r fail_array fail_assembly <<<"$fail"
log "submitted: ball array $fail_array with chunk 1's stats file blocked (assembly $fail_assembly)"
wait_jobs "$fail_array" "$fail_assembly"
status_text=$("$retrace" farm status "$fail_array" "$fail_assembly")
printf '%s\n' "$status_text" | tee "$work/status-2.txt" >&2
grep -qE "^${fail_array}_1 +retrace-render +FAILED +exit 1 " <<<"$status_text" ||
  fail "farm status does not name task 1 as failed with exit 1"
grep -q "task 1 of $fail_array FAILED (exit 1)" <<<"$status_text" || fail "farm status' summary does not name task 1"
grep -qE "^${fail_array}_[02] +retrace-render +COMPLETED" <<<"$status_text" || fail "the other tasks did not complete"
assembly_state=$(states "$fail_assembly")
[[ $assembly_state != COMPLETED && $assembly_state != RUNNING ]] || fail "the assembly job ran: $assembly_state"
[[ ! -e $work/fail/report.md && ! -e $work/fail/animation.gif ]] || fail "the assembly wrote its files"
grep -q "Is a directory\|cannot" "$work/fail/logs/render-${fail_array}_1.log" ||
  fail "task 1's log does not say why it failed"
log "task 1 failed with exit 1; the assembly job did not run ($assembly_state, $(squeue -h -j "$fail_assembly" -t all -o %r))"
scancel "$fail_assembly"

# --------------------------------------------------------------- 3. a requeue in the second of its cancel
# slurmd refuses to launch a job whose credential dates from the second the
# job was killed in; the task then fails with exit 1 without running. Task 1
# is cancelled just after a second begins and requeued at once; cancelling
# task 0 next ends a job, which starts a scheduling pass in that same second.
submit quick scenes/paper-bounce.toml --chunks 2 --spp 16 -o "$work/quick/frame_####.png"
read -r quick_array quick_assembly <<<"$quick"
# Past their full first frames, the tasks stop within milliseconds.
wait_for 60 "task 0 of $quick_array to write frame 2" test -e "$work/quick/frame_0002.png"
wait_for 60 "task 1 of $quick_array to write frame 52" test -e "$work/quick/frame_0052.png"
sleep "$(date +%N | awk '{print (1e9 - $1) / 1e9 + 0.02}')"
scancel "${quick_array}_1"
cancelled_at=$(date +%s.%N)
wait_for 10 "task 1 of $quick_array to be cancelled" cancelled "${quick_array}_1"
"$retrace" farm requeue "$quick_array" 1 >&2
# Task 0 has some 45 frames left, seconds of work.
[[ $(states "${quick_array}_0") == RUNNING ]] || fail "task 0 of $quick_array ended before the requeue: nothing tested"
scancel "${quick_array}_0"
log "array $quick_array: task 1 cancelled and requeued, task 0 cancelled, within $(awk -v a="$cancelled_at" -v b="$(date +%s.%N)" 'BEGIN {printf "%.2f", b - a}') s"
wait_jobs "$quick_array"
grep -q "Restarts=1" <(scontrol -o show job "${quick_array}_1") || fail "task 1 of $quick_array was not restarted once"
[[ $(states "${quick_array}_1") == COMPLETED ]] ||
  fail "task 1 of $quick_array, requeued in the second of its cancel: $("$retrace" farm status "$quick_array" | grep "^${quick_array}_1 ")"
grep -q "restart 1" "$work/quick/logs/render-${quick_array}_1.log" || fail "the requeued task 1 of $quick_array did not run again"
log "task 1, requeued in the second of its cancel, ran again and completed"
scancel "$quick_assembly"
