#!/usr/bin/env bash
# Builds tessera's container image without pulling anything: first the static binary
# (target x86_64-unknown-linux-musl, cargo profile `container`, render only: pure Rust, so
# no C compiler is needed), then the image from deploy/container/Containerfile, labelled
# with the version, the commit and the source.
# Prints the image's two tags, the version's first:
#
#   tessera:0.1.0
#   tessera:0.1.0-<commit>
#
# ENGINE=docker builds with Docker instead of Podman; SOURCE sets the source label (default:
# the git remote `origin`). Further arguments go to the engine's `build`; -h or --help,
# first, prints this.
set -euo pipefail
# -h or --help first: this header, before anything is built.
case "${1:-}" in
-h | --help)
  sed -n '2,/^set /{/^#/s/^# \{0,1\}//p}' "$0"
  exit 0
  ;;
esac
cd "$(dirname "$0")/../.."
engine=${ENGINE:-podman}
target=x86_64-unknown-linux-musl
if command -v rustup >/dev/null && ! rustup target list --installed | grep -qx "$target"; then
  rustup target add "$target" >&2
fi
# The image renders, merges, benchmarks and reproduces: render only, without the results
# database (kept where results are kept, not in a container) or the live viewer's server.
cargo build --locked --profile container --target "$target" --no-default-features >&2
# The binary where the Containerfile (and .dockerignore) take it, when CARGO_TARGET_DIR put
# it elsewhere.
binary=target/$target/container/tessera
built=${CARGO_TARGET_DIR:-target}/$target/container/tessera
if [ "$(realpath -m "$built")" != "$(realpath -m "$binary")" ]; then
  mkdir -p "$(dirname "$binary")"
  cp "$built" "$binary"
fi

version=$(sed -n 's/^version = "\(.*\)"$/\1/p' Cargo.toml | head -n 1)
revision=$(git rev-parse HEAD 2>/dev/null || echo unknown)
# As the binary's own commit says: `-dirty` when what is compiled in differs from it.
if [ "$revision" != unknown ] &&
  [ -n "$(git --no-optional-locks status --porcelain -- src benches scenes Cargo.toml Cargo.lock build.rs)" ]; then
  revision="$revision-dirty"
fi
source=${SOURCE:-$(git config --get remote.origin.url 2>/dev/null || echo unknown)}
# The commit's time, not the build's, so that the same commit builds the same image.
epoch=$(git log -1 --format=%ct 2>/dev/null || echo 0)
created=$(date -u -d "@$epoch" +%Y-%m-%dT%H:%M:%SZ)
tags=("tessera:$version")
short=${revision:0:12}
[[ $revision == *-dirty ]] && short="$short-dirty"
[ "$revision" != unknown ] && tags+=("tessera:$version-$short")

args=(-f deploy/container/Containerfile
  --build-arg "VERSION=$version" --build-arg "REVISION=$revision"
  --build-arg "SOURCE=$source" --build-arg "CREATED=$created")
for tag in "${tags[@]}"; do args+=(-t "$tag"); done
[ "$engine" = podman ] && args+=(--timestamp "$epoch")
"$engine" build "${args[@]}" "$@" . >&2
printf '%s\n' "${tags[@]}"
