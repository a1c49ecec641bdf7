#!/bin/sh
# Build the book-2 reference renderer: tests/data/book2-cpp/build.sh OUTPUT_BINARY
# Compiles reference.cc against the book's own headers in this folder. No network.
set -eu
if [ "$#" -ne 1 ]; then
    echo "usage: $0 OUTPUT_BINARY" >&2
    exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
out=$1
# Always g++: the book's multi-draw expressions (vec3::random(), point3 center(...)) depend on the
# compiler's argument evaluation order, and GCC's (right to left) is part of this reference.
if ! command -v g++ >/dev/null 2>&1; then
    echo "$0: g++ not found" >&2
    exit 1
fi
if ! g++ -O2 -std=c++17 \
        -I "$here/TheNextWeek" -I "$here/common" \
        -o "$out" "$here/reference.cc"; then
    echo "$0: compiling $here/reference.cc failed" >&2
    exit 1
fi
echo "built $out" >&2
