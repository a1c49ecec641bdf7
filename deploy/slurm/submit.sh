#!/usr/bin/env bash
# Queues an N-task render array and a merge that waits for all of it to succeed.
#   usage: deploy/slurm/submit.sh N [sbatch options...]
#   e.g.   SCENE=scenes/cover.toml EXTRA="--spp 4000" IMAGE=cover.exr deploy/slurm/submit.sh 16
#
# CONTAINER=IMAGE runs tessera from that container image (deploy/container/) with Podman on
# the nodes, through podman-tessera, instead of the binary TESSERA.
#
# Each task gets CPUS_PER_TASK CPUs; by default as many as the smallest node has, taken from
# Slurm (`sinfo`), so a task fills a node whatever its size. sbatch options given after N
# (e.g. --partition, --cpus-per-task) override these. Prints the two job ids:
#   render <array job id>
#   merge <merge job id>
set -euo pipefail
here=$(dirname "$0")
n=${1:?usage: submit.sh N [sbatch options...]}
shift
case $n in
'' | *[!0-9]*) echo "submit.sh: N must be a positive number of tasks, got '$n'" >&2 && exit 2 ;;
esac
# Decimal, whatever zeros lead it: bash reads 010 as octal (8) and 08 as an error; and of
# at most nine digits, where bash's arithmetic would wrap 20 of them round.
given=$n
digits=$(printf '%s' "$n" | sed 's/^0*//')
[ "${#digits}" -le 9 ] || { echo "submit.sh: N must be a positive number of tasks, at most 999999999, got '$given'" >&2 && exit 2; }
n=$((10#$n))
[ "$n" -gt 0 ] || { echo "submit.sh: N must be a positive number of tasks, got '$given'" >&2 && exit 2; }
export SCENE=${SCENE:-scenes/cover.toml} OUTDIR=${OUTDIR:-parts} EXTRA=${EXTRA:-}
export IMAGE=${IMAGE:-render.png} TESSERA=${TESSERA:-tessera}
if [ -n "${CONTAINER:-}" ]; then
  TESSERA="$(cd "$here" && pwd)/podman-tessera"
  export CONTAINER
fi
cpus=${CPUS_PER_TASK:-$(sinfo -h -N -o %c | tr -d '+' | sort -n | head -n 1)}
[ -n "$cpus" ] || { echo "submit.sh: sinfo lists no nodes" >&2 && exit 2; }
array=$(sbatch --parsable --export=ALL --array=0-$((n - 1)) --cpus-per-task="$cpus" \
  "$@" "$here/render.sbatch")
array=${array%%;*}
# If a task fails for good, the merge is cancelled instead of pending forever.
merge=$(sbatch --parsable --export=ALL --dependency=afterok:"$array" --kill-on-invalid-dep=yes \
  "$@" "$here/merge.sbatch")
echo "render $array"
echo "merge ${merge%%;*}"
