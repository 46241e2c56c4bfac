#!/usr/bin/env bash
# Builds libpinshim.so, the C ABI over pinocchio 4.1 that `cargo bench --bench vs_pinocchio`
# loads, against pinocchio's PyPI wheel (C++ headers and libraries under cmeel.prefix).
#
#   benches/pinocchio/build.sh [--native] [OUT_DIR]
#
# OUT_DIR defaults to $CARGO_TARGET_DIR/pinocchio (target/pinocchio): the virtual environment
# and the library go there, never into the source tree. --native adds -march=native and names
# the library libpinshim_native.so (tuned to this CPU; other CPUs may not run it). The last
# line printed is the library's path.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
march=()
name=libpinshim.so
if [[ "${1:-}" == "--native" ]]; then
  # Eigen's alignment and heap allocator stay the wheel's (16 bytes, plain malloc): the Model
  # the wheel's parser fills is used and freed here. GCC 12 warns about Eigen's 8-wide stores
  # into 6-row blocks in pinocchio's composite joints, which URDFs never create.
  march=(-march=native -DEIGEN_MAX_ALIGN_BYTES=16 -DEIGEN_MALLOC_ALREADY_ALIGNED=1 -Wno-stringop-overread)
  name=libpinshim_native.so
  shift
fi
out="${1:-${CARGO_TARGET_DIR:-$root/target}/pinocchio}"
mkdir -p "$out"
out="$(cd "$out" && pwd)"

python="${PYTHON:-python3}"
if [[ ! -x "$out/venv/bin/python" ]]; then
  "$python" -m venv "$out/venv"
fi
# pin pulls the libraries (pinocchio, urdfdom, boost); the headers pinocchio's headers include
# come from the wheels of its build dependencies: Eigen 3.4.1 and urdfdom_headers 3.0.0, the
# versions the 4.1.0 wheel was built with (its CMake files ask for urdfdom_headers 3).
"$out/venv/bin/python" -m pip install --quiet --disable-pip-version-check \
  pin==4.1.0 cmeel-eigen==3.4.1 cmeel-urdfdom-headers==3.0.0
"$out/venv/bin/python" -m pip freeze --disable-pip-version-check > "$out/versions.txt"

prefix="$("$out/venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')/cmeel.prefix"

# The definitions are those of pinocchio's exported CMake targets (pinocchio_headers and
# pinocchio_parsers) except PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION: without it the timed
# algorithms are compiled here, with these flags, instead of called in the wheel's build.
# Hidden visibility keeps this library's copies of pinocchio's templates to itself: exported,
# they would replace the ones the wheel's URDF parser calls, and with --native their code would
# not match the parser's.
"${CXX:-c++}" -std=c++17 -O3 -DNDEBUG "${march[@]}" -fPIC -shared \
  -fvisibility=hidden -fvisibility-inlines-hidden \
  -DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30 \
  -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS -DBOOST_FUSION_INVOKE_MAX_ARITY=12 \
  -DPINOCCHIO_WITH_URDFDOM -DPINOCCHIO_URDFDOM_HEADERS_MAJOR_VERSION=3 \
  -DPINOCCHIO_URDFDOM_HEADERS_MINOR_VERSION=0 -DPINOCCHIO_URDFDOM_HEADERS_PATCH_VERSION=0 \
  -I"$prefix/include" -I"$prefix/include/eigen3" -I"$prefix/include/urdfdom_headers" \
  -I"$prefix/include/urdfdom" \
  "$here/shim.cpp" -o "$out/$name" \
  -L"$prefix/lib" -Wl,-rpath,"$prefix/lib" -lpinocchio_parsers -lpinocchio_default -lurdfdom_model \
  -lconsole_bridge

echo "$out/$name"
