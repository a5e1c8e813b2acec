# Shared by the launch scripts (sourced, not run). The caller defines `step`.

# Installs those of the given Debian packages that are missing (with sudo when not root).
# Returns non-zero, having installed nothing, on a machine without apt-get.
ensure_debian_packages() {
    local missing=() p sudo=""
    for p in "$@"; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
    done
    [ ${#missing[@]} -gt 0 ] || return 0
    command -v apt-get >/dev/null || { echo "apt-get not found; install by hand: ${missing[*]}" >&2; return 1; }
    step "installing Debian packages: ${missing[*]}"
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
}
