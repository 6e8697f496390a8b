#!/usr/bin/env bash
# A sharded fit on a real Slurm: installs Debian's slurm-wlm and munge (root), starts a
# one-node cluster on localhost, submits scripts/cluster/fit_array.sbatch as a job
# array of N parts, joins them with a dependent `relit merge` job, and checks that the
# merged file relights to exactly the single-process fit's images.
#
#   scripts/cluster/slurm_test.sh [CAPTURE] [PARTS]
#
# CAPTURE defaults to ../shared/data/realrti/item1/dirs.lp (a studio capture where that
# is missing), PARTS to 4. RELIT names the binary (default target/release/relit, built
# if missing). Everything it starts is stopped at the end; exit status 0 only when the
# images are identical.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
parts=${2:-4}
relit=${RELIT:-$root/target/release/relit}
[[ -x $relit ]] || (cd "$root" && cargo build --release -q)
relit=$(realpath "$relit")
work=$(mktemp -d /tmp/relit-slurm.XXXXXX)
chmod 755 "$work"
log() { printf '[slurm_test %5.1fs] %s\n' "$SECONDS" "$*"; }

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
    [[ $(id -u) == 0 ]] || { echo "slurm_test: needs root to install slurm-wlm and munge" >&2; exit 1; }
    log "installing slurm-wlm and munge"
    export DEBIAN_FRONTEND=noninteractive
    apt-get install -y -q slurm-wlm munge >/dev/null 2>&1 \
        || { apt-get update -q >/dev/null && apt-get install -y -q slurm-wlm munge >/dev/null; }
fi
[[ $(id -u) == 0 ]] || { echo "slurm_test: starts slurmctld/slurmd as root" >&2; exit 1; }

capture=${1:-}
if [[ -z $capture ]]; then
    capture=$root/../shared/data/realrti/item1/dirs.lp
    if [[ ! -f $capture ]]; then
        log "no shared data: rendering a studio capture"
        "$relit" capture box --lights hemisphere:48 --size 256x192 --out "$work/capture" -q >/dev/null
        capture=$work/capture/capture.json
    fi
fi
capture=$(realpath "$capture")

# --- munge: a fresh key, its own socket, so that a munged already running is untouched.
mkdir -p "$work/munge"
dd if=/dev/urandom of="$work/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$work/munge/munge.key"
munge_socket=$work/munge/munge.socket
munged --force --key-file="$work/munge/munge.key" --socket="$munge_socket" \
    --pid-file="$work/munge/munged.pid" --log-file="$work/munge/munged.log" \
    --seed-file="$work/munge/munged.seed"

# --- slurm: one node (this machine), every core, ports of their own.
host=$(hostname -s)
cpus=$(nproc)
mem=$(awk '/MemTotal/ {print int($2 / 1024 * 0.8)}' /proc/meminfo)
mkdir -p "$work/state" "$work/spool"
export SLURM_CONF=$work/slurm.conf
cat >"$SLURM_CONF" <<CONF
ClusterName=relit-test
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=${SLURMCTLD_PORT:-16817}
SlurmdPort=${SLURMD_PORT:-16818}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$munge_socket
CredType=cred/munge
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/builtin
# Run the queue every second: dependent jobs (plan → array → merge) start at once.
SchedulerParameters=sched_interval=1
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
CONF

status=1
cleanup() {
    # Stop the daemons (their pid files are in $work), wait until they are gone, then
    # remove $work unless kept. slurmctld saves its state while it shuts down: removing
    # the folder under it once failed ("Directory not empty") after a passing test, so
    # the wait follows the daemons' own pids and the removal is retried; a folder that
    # still cannot be removed is reported, and does not turn a pass into a failure.
    scontrol shutdown >/dev/null 2>&1 || true
    local pids=()
    for file in "$work/slurmctld.pid" "$work/slurmd.pid" "$work/munge/munged.pid"; do
        [[ -f $file ]] && pids+=("$(cat "$file" 2>/dev/null)")
    done
    for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
    for _ in $(seq 40); do
        local alive=0
        for pid in "${pids[@]}"; do kill -0 "$pid" 2>/dev/null && alive=1; done
        pgrep -f "$work" >/dev/null 2>&1 && alive=1
        [[ $alive == 0 ]] && break
        sleep 0.25
    done
    for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null || true; done
    pkill -KILL -f "$work" 2>/dev/null || true
    if [[ $status == 0 ]]; then
        for _ in $(seq 5); do
            rm -rf "$work" 2>/dev/null && break
            sleep 1
        done
        [[ ! -e $work ]] || echo "slurm_test: could not remove $work" >&2
    else
        echo "slurm_test: files and logs kept in $work" >&2
    fi
    return 0
}
trap cleanup EXIT

slurmctld -i
slurmd
log "one-node cluster $host ($cpus CPUs) starting"
for _ in $(seq 60); do
    state=$(sinfo -h -o %t 2>/dev/null || true)
    [[ $state == idle* ]] && break
    sleep 1
done
[[ ${state:-} == idle* ]] || { echo "slurm_test: the node never became idle (state '${state:-none}'); logs in $work" >&2; exit 1; }
log "node $host is $state"

# --- the reference: one process, the whole capture.
log "single-process fit of $capture"
start=$SECONDS
"$relit" fit "$capture" -o "$work/single.exr" --quiet --json >"$work/single.json"
single_s=$((SECONDS - start))

# --- the same fit as a job array of $parts parts and a merge after it: first with every
# part making the choices itself, then with a plan job they all depend on.
run_array() { # NAME [PLAN]
    local name=$1 plan=${2:-} start=$SECONDS dep=() array merge
    if [[ -n $plan ]]; then
        local planjob
        planjob=$(sbatch --parsable --chdir="$work" --output="$work/plan.out" \
            --wrap "'$relit' plan '$capture' -o '$plan' --quiet")
        dep=(--dependency=afterok:"$planjob")
        log "$name: submitted plan job $planjob"
    fi
    array=$(sbatch --parsable --chdir="$work" --array=0-$((parts - 1)) "${dep[@]}" \
        --cpus-per-task=1 --export=ALL,RELIT="$relit",PLAN="$plan" \
        "$root/scripts/cluster/fit_array.sbatch" "$capture" "$work/$name")
    log "$name: submitted job array $array ($parts tasks)"
    merge=$(sbatch --parsable --chdir="$work" --dependency=afterok:"$array" \
        --output="$work/merge_$name.out" \
        --wrap "'$relit' merge '$work/$name'/part_*.exr -o '$work/$name.exr'")
    # `sbatch --wait` polls at growing intervals (up to 32 s); ask every half second.
    local state=""
    for _ in $(seq 1200); do
        state=$(scontrol show job "$merge" -o 2>/dev/null | grep -o 'JobState=[A-Z_]*' | cut -d= -f2)
        case $state in COMPLETED | FAILED | CANCELLED | TIMEOUT | NODE_FAIL | OUT_OF_MEMORY) break ;; esac
        sleep 0.5
    done
    [[ $state == COMPLETED ]] \
        || { echo "slurm_test: the $name merge job ended $state:" >&2; cat "$work"/*.out >&2 || true; return 1; }
    cat "$work/merge_$name.out"
    log "$name: array and merge done in $((SECONDS - start)) s"
}
run_array merged
run_array planned "$work/plan.json"

# --- identical relit images: several directional lights, compared value for value.
identical=1
for light in 0.3,0.4,0.8 -0.6,0.2,0.5 0,0,1 0.8,-0.3,0.4; do
    "$relit" relight "$work/single.exr" --light "dir:$light" -o "$work/single_$light.exr" >/dev/null
    for name in merged planned; do
        "$relit" relight "$work/$name.exr" --light "dir:$light" -o "$work/${name}_$light.exr" >/dev/null
        max=$("$relit" compare "$work/${name}_$light.exr" "$work/single_$light.exr" --json \
            | python3 -c 'import json,sys; print(json.load(sys.stdin)["max_abs_error"])')
        if [[ $max == 0.0 ]]; then
            log "light $light: $name parts and the single fit relight identically (largest difference 0)"
        else
            log "light $light: $name parts: largest difference $max: NOT identical"
            identical=0
        fi
    done
done
log "single-process fit ${single_s} s on $cpus CPUs; per part (1 CPU each):"
for name in merged planned; do
    python3 - "$work/$name" <<'PY'
import json, pathlib, sys
parts = sorted(pathlib.Path(sys.argv[1]).glob("part_*.json"))
s = [json.loads(p.read_text())["seconds"] for p in parts]
mib = [json.loads(p.read_text())["peak_rss_bytes"] / 2**20 for p in parts]
print(f"  {pathlib.Path(sys.argv[1]).name}: {len(s)} parts, fit {min(s):.2f}-{max(s):.2f} s each "
      f"(total {sum(s):.2f} s), peak memory {min(mib):.0f}-{max(mib):.0f} MiB")
PY
done
if [[ $identical == 1 ]]; then status=0; echo "slurm_test: ok"; else echo "slurm_test: FAILED"; fi
exit $status
