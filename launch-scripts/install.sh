#!/usr/bin/env bash
# Installs the RTAPI like a library, so that C, C++ and Python clients build and run against it
# as they would against the product:
#
#   PREFIX/include/RTAPI.h
#   PREFIX/lib/librtapi.so.VERSION, librtapi.so.0 (the SONAME), librtapi.so, librtapi.a
#   PREFIX/lib/libOpalOrchestra.so            the product's library name (its clients' builds
#                                             look for OpalOrchestra and RTAPI.h): the same
#                                             library with its own SONAME, so that it works
#                                             alone in a directory of its own
# Libraries and the CLI are installed stripped of debug information.
#   PREFIX/lib/pkgconfig/rtapi.pc             pkg-config --cflags --libs rtapi
#   PREFIX/lib/cmake/tutti/tuttiConfig.cmake  find_package(tutti) -> imported target tutti::rtapi
#   PREFIX/bin/tutti                          the CLI, when it was built
#
# Usage: launch-scripts/install.sh [--prefix DIR] [--destdir DIR] [--build-dir DIR] [--no-cli]
#   --prefix DIR     where to install (default /usr/local)
#   --destdir DIR    stage the files under DIR/PREFIX, as a package is built, while the
#                    pkg-config file names PREFIX (PREFIX must then be absolute)
#   --build-dir DIR  take the built library from DIR (e.g. target/debug) instead of
#                    target/release, which is built (cargo build --release -p tutti-rtapi)
#                    unless it is newer than every source it is made of
#   --no-cli         do not install the tutti CLI even when DIR has it
# The Python module installs with pip: pip install ./python (it finds the library through
# pkg-config, so add PREFIX/lib/pkgconfig to PKG_CONFIG_PATH for a prefix pip does not know).
set -euo pipefail
cd "$(dirname "$0")/.."

prefix=/usr/local
destdir=""
build_dir=""
cli=yes
while [ $# -gt 0 ]; do
    case "$1" in
        --prefix) prefix="${2:?--prefix needs a directory}"; shift 2 ;;
        --prefix=*) prefix="${1#--prefix=}"; shift ;;
        --destdir) destdir="${2:?--destdir needs a directory}"; shift 2 ;;
        --destdir=*) destdir="${1#--destdir=}"; shift ;;
        --build-dir) build_dir="${2:?--build-dir needs a directory}"; shift 2 ;;
        --build-dir=*) build_dir="${1#--build-dir=}"; shift ;;
        --no-cli) cli=no; shift ;;
        -h|--help) sed -n '2,24p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "install.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
    esac
done

if [ -z "$build_dir" ]; then
    build_dir=target/release
    # A workspace build may have made it already: cargo would build it again for -p alone
    # (the features it unifies differ), so only what is out of date is built.
    if [ -f "$build_dir/librtapi.so" ] && [ -f "$build_dir/librtapi.a" ] \
        && [ -z "$(find crates/tutti-core crates/tutti-rtapi include Cargo.toml Cargo.lock -newer "$build_dir/librtapi.so" -print -quit)" ]; then
        echo "the RTAPI library in $build_dir is up to date"
    else
        echo "building the RTAPI library (release)"
        cargo build --release --locked -p tutti-rtapi
    fi
fi
for tool in cc strip; do
    command -v "$tool" >/dev/null || { echo "install.sh: '$tool' is missing (apt-get install gcc binutils)" >&2; exit 2; }
done
for f in librtapi.so librtapi.a; do
    [ -f "$build_dir/$f" ] || { echo "install.sh: $build_dir/$f missing: build it first (cargo build -p tutti-rtapi)" >&2; exit 2; }
done

version=$(sed -n 's/^version *= *"\(.*\)"/\1/p' Cargo.toml | head -1)
major=${version%%.*}
if [ -n "$destdir" ]; then
    case "$prefix" in /*) ;; *) echo "install.sh: --destdir needs an absolute --prefix, not '$prefix'" >&2; exit 2 ;; esac
    mkdir -p "$destdir"
    destdir=$(cd "$destdir" && pwd)
else
    prefix=$(mkdir -p "$prefix" && cd "$prefix" && pwd)
fi
# Files go under $root; what they say of where they are names $prefix.
root="$destdir$prefix"
lib="$root/lib"
mkdir -p "$root/include" "$lib/pkgconfig" "$lib/cmake/tutti"

install -m 0644 include/RTAPI.h "$root/include/RTAPI.h"
install -m 0755 "$build_dir/librtapi.so" "$lib/librtapi.so.$version"
install -m 0644 "$build_dir/librtapi.a" "$lib/librtapi.a"
strip --strip-unneeded "$lib/librtapi.so.$version"
strip --strip-debug "$lib/librtapi.a"
ln -sfn "librtapi.so.$version" "$lib/librtapi.so.$major"
ln -sfn "librtapi.so.$major" "$lib/librtapi.so"
# The product's name as a library of its own (SONAME libOpalOrchestra.so), linked from the
# static library: a client linked against it needs nothing beside it. Only the RT* calls
# are exported. A process loads one of the two libraries, not both (each has its own state).
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
printf '{ global: RT*; local: *; };\n' > "$scratch/exports.map"
rm -f "$lib/libOpalOrchestra.so"
cc -shared -o "$lib/libOpalOrchestra.so" -Wl,-soname,libOpalOrchestra.so \
    -Wl,--version-script="$scratch/exports.map" -Wl,--gc-sections \
    -Wl,--whole-archive "$lib/librtapi.a" -Wl,--no-whole-archive -lpthread -ldl -lm
strip --strip-unneeded "$lib/libOpalOrchestra.so"
if [ "$cli" = yes ] && [ -x "$build_dir/tutti" ]; then
    mkdir -p "$root/bin"
    install -m 0755 "$build_dir/tutti" "$root/bin/tutti"
    strip --strip-debug "$root/bin/tutti"
fi

cat > "$lib/pkgconfig/rtapi.pc" <<PC
prefix=$prefix
libdir=\${prefix}/lib
includedir=\${prefix}/include

Name: rtapi
Description: tutti's RTAPI, source-compatible with the RTAPI of RT-LAB Orchestra
Version: $version
Cflags: -I\${includedir}
Libs: -L\${libdir} -lrtapi
Libs.private: -lpthread -ldl -lm
PC

cat > "$lib/cmake/tutti/tuttiConfig.cmake" <<'CMAKE'
# find_package(tutti): the imported targets tutti::rtapi (librtapi.so) and tutti::rtapi_static
# (librtapi.a), with RTAPI.h on their include path. Relocatable: paths are taken from where
# this file lies (PREFIX/lib/cmake/tutti).
get_filename_component(_tutti_prefix "${CMAKE_CURRENT_LIST_DIR}/../../.." ABSOLUTE)
if(NOT TARGET tutti::rtapi)
  add_library(tutti::rtapi SHARED IMPORTED)
  set_target_properties(tutti::rtapi PROPERTIES
    IMPORTED_LOCATION "${_tutti_prefix}/lib/librtapi.so"
    IMPORTED_SONAME "librtapi.so.0"
    INTERFACE_INCLUDE_DIRECTORIES "${_tutti_prefix}/include")
  add_library(tutti::rtapi_static STATIC IMPORTED)
  set_target_properties(tutti::rtapi_static PROPERTIES
    IMPORTED_LOCATION "${_tutti_prefix}/lib/librtapi.a"
    INTERFACE_INCLUDE_DIRECTORIES "${_tutti_prefix}/include"
    INTERFACE_LINK_LIBRARIES "pthread;dl;m")
endif()
set(tutti_INCLUDE_DIRS "${_tutti_prefix}/include")
set(tutti_LIBRARIES tutti::rtapi)
unset(_tutti_prefix)
CMAKE

cat > "$lib/cmake/tutti/tuttiConfigVersion.cmake" <<CMAKE
set(PACKAGE_VERSION "$version")
if(PACKAGE_FIND_VERSION VERSION_GREATER PACKAGE_VERSION)
  set(PACKAGE_VERSION_COMPATIBLE FALSE)
else()
  set(PACKAGE_VERSION_COMPATIBLE TRUE)
  if(PACKAGE_FIND_VERSION STREQUAL PACKAGE_VERSION)
    set(PACKAGE_VERSION_EXACT TRUE)
  endif()
endif()
CMAKE

echo "installed the RTAPI $version under $root"
echo "  C/C++:  pkg-config --cflags --libs rtapi   (PKG_CONFIG_PATH=$lib/pkgconfig)"
echo "  CMake:  find_package(tutti) with CMAKE_PREFIX_PATH=$prefix -> tutti::rtapi"
echo "  Python: pip install ./python"
