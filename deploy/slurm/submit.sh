#!/usr/bin/env bash
# Queues an N-task render array and a merge that waits for all of it to succeed.
#   usage: deploy/slurm/submit.sh N [render.sbatch options...]
#   e.g.   SCENE=scenes/cover.toml EXTRA="--spp 4000" IMAGE=cover.exr deploy/slurm/submit.sh 16
set -euo pipefail
here=$(dirname "$0")
n=${1:?usage: submit.sh N}
shift
export SCENE=${SCENE:-scenes/cover.toml} OUTDIR=${OUTDIR:-parts} EXTRA=${EXTRA:-} IMAGE=${IMAGE:-render.png}
array=$(sbatch --parsable --export=ALL --array=0-$((n - 1)) "$@" "$here/render.sbatch")
sbatch --export=ALL --dependency=afterok:"$array" "$here/merge.sbatch"
