#!/usr/bin/env bash
# Builds the docs site (docs/install.md, "The docs site") into target/book: docs/ as an mdBook,
# with the API reference of `cargo doc --workspace --no-deps` under api/, then checks it:
# any warning or error of mdBook, and any broken link of the site or path into the code
# (tests/docs/check_site.py), fails the build.
#
# Usage: launch-scripts/docs.sh [--no-api]
#   --no-api   take the API reference as target/doc already has it (the test command has just
#              built it with warnings as errors) instead of running cargo doc
#
# mdBook 0.5.4 is installed with cargo into ~/.cache/tutti/tools/mdbook-0.5.4 the first time
# (about 3 minutes on 2 cores), or taken from MDBOOK when set. Open target/book/index.html.
set -euo pipefail
cd "$(dirname "$0")/.."

api=yes
while [ $# -gt 0 ]; do
    case "$1" in
        --no-api) api=no; shift ;;
        -h|--help) sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "docs.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
    esac
done

version=0.5.4
mdbook="${MDBOOK:-}"
if [ -z "$mdbook" ]; then
    tools="${XDG_CACHE_HOME:-$HOME/.cache}/tutti/tools/mdbook-$version"
    mdbook="$tools/bin/mdbook"
    if ! [ -x "$mdbook" ]; then
        echo "installing mdbook $version into $tools"
        cargo install --quiet --locked mdbook --version "$version" --no-default-features --features search --root "$tools"
    fi
fi

if [ "$api" = yes ]; then
    RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked --quiet
fi
[ -f target/doc/tutti_core/index.html ] || { echo "docs.sh: target/doc has no API reference: run cargo doc --workspace --no-deps" >&2; exit 2; }

rm -rf target/book
log=$(mktemp)
trap 'rm -f "$log"' EXIT
if ! "$mdbook" build 2>"$log"; then
    cat "$log" >&2
    echo "docs.sh: mdbook build failed" >&2
    exit 1
fi
if grep -E '(^|[[:space:]])(WARN|ERROR)[[:space:]]' "$log" >&2; then
    echo "docs.sh: mdbook warned (above): warnings are errors" >&2
    exit 1
fi
cp -r target/doc target/book/api
python3 tests/docs/check_site.py target/book docs .
echo "the docs site: target/book/index.html"
