#!/usr/bin/env bash
# Runs the crate's tests against Embree 4 (Debian 13's libembree-dev 4.3.x)
# on a Debian 12 machine, whose own Embree is 3.13: inside a Debian 13
# (trixie) chroot made with debootstrap, using the host's Rust toolchain.
#
#   bash .ci/embree4.sh                      # cargo test --all-targets
#   bash .ci/embree4.sh cargo test --release # ... and then this command too
#
# Runs as root (CI), or through sudo (then cargo runs as the calling user).
# The chroot is built once, at $EMBREE4_CHROOT (default: <repo>/.embree4-chroot),
# and reused while its stamp file says it is complete; EMBREE4_REBUILD=1
# rebuilds it. Builds inside go to $EMBREE4_TARGET_DIR (default:
# <repo>/target-embree4), apart from the host's target/: build scripts built
# there need Debian 13's glibc.
#
# Every mount lives in a private mount namespace when possible (so nothing is
# left mounted even after kill -9; EMBREE4_NO_UNSHARE=1 mounts in the host's
# namespace instead) and is unmounted on exit in any case; a rerun first
# unmounts whatever a killed run left behind.
set -euo pipefail

SUITE=trixie
MIRROR=${EMBREE4_MIRROR:-http://deb.debian.org/debian}
# And whatever else the tests need, from the Makefile (the window's X
# server and tools, the OBJ test models), so the suite runs whole in here.
# shellcheck disable=SC2206 # a space-separated list, split on purpose
PACKAGES=(libembree-dev libclang-dev clang pkg-config gcc libc6-dev ca-certificates
          ${EMBREE4_EXTRA_PACKAGES:-})
STAMP_NAME=.embree4-ready           # holds the package list it was made with
BOOTSTRAPPED_NAME=.embree4-bootstrapped
MARKER_NAME=.embree4-chroot-marker  # "this directory is ours to delete"

log() { printf 'embree4: %s\n' "$*" >&2; }
die() { log "error: $*"; exit 1; }

# No stdin at all (CI): give children /dev/null rather than a closed fd 0.
{ true <&0; } 2>/dev/null || exec </dev/null

REPO=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd -P)
ROOT=$(realpath -m "${EMBREE4_CHROOT:-$REPO/.embree4-chroot}")
TARGET_DIR=$(realpath -m "${EMBREE4_TARGET_DIR:-$REPO/target-embree4}")

[[ $EUID -eq 0 ]] || die "must run as root, e.g. sudo bash .ci/embree4.sh $*"
[[ $ROOT != / && $REPO/ != "$ROOT"/* ]] \
    || die "EMBREE4_CHROOT=$ROOT must not be / or contain the repository"

# Whose toolchain and files: the sudo caller's if there is one, else root's.
RUN_AS=
if [[ -n ${SUDO_UID:-} && ${SUDO_UID} != 0 ]]; then
    RUN_AS=$SUDO_UID:$SUDO_GID
    USER_HOME=$(getent passwd "$SUDO_UID" | cut -d: -f6)
    CARGO_HOME_DIR=$USER_HOME/.cargo
    RUSTUP_HOME_DIR=$USER_HOME/.rustup
else
    USER_HOME=$HOME
    CARGO_HOME_DIR=${CARGO_HOME:-$HOME/.cargo}
    RUSTUP_HOME_DIR=${RUSTUP_HOME:-$HOME/.rustup}
fi
USER_HOME=$(realpath -m "$USER_HOME")
CARGO_HOME_DIR=$(realpath -m "$CARGO_HOME_DIR")
RUSTUP_HOME_DIR=$(realpath -m "$RUSTUP_HOME_DIR")
[[ -x $CARGO_HOME_DIR/bin/cargo ]] \
    || die "no cargo in $CARGO_HOME_DIR/bin (the host toolchain must come from rustup)"
[[ -d $RUSTUP_HOME_DIR/toolchains ]] || die "no rustup toolchains in $RUSTUP_HOME_DIR"

# --- mounts -----------------------------------------------------------------

# Mount points at or under $ROOT in this namespace, deepest (latest) first.
mounts_under_root() {
    local _id _parent _dev _fsroot mp _rest
    tac /proc/self/mountinfo | while read -r _id _parent _dev _fsroot mp _rest; do
        mp=${mp//\\040/ }
        if [[ $mp == "$ROOT" || $mp == "$ROOT"/* ]]; then printf '%s\n' "$mp"; fi
    done
}

unmount_all() {
    local mp
    while IFS= read -r mp; do
        umount "$mp" 2>/dev/null || umount -l "$mp" || log "warning: could not unmount $mp"
    done < <(mounts_under_root)
}

# mount_once TARGET MOUNT-ARGS...: mounts unless TARGET is already a mount point.
mount_once() {
    local target=$1
    shift
    mkdir -p "$target"
    if ! mountpoint -q "$target"; then
        mount "$@" "$target"
    fi
}

# bind_once SRC [ro]: SRC at the same absolute path inside the chroot.
bind_once() {
    local src=$1 target=$ROOT$1
    mkdir -p "$target"
    if ! mountpoint -q "$target"; then
        mount --bind "$src" "$target"
        mount --make-private "$target"
        if [[ ${2:-} == ro ]]; then
            mount -o remount,bind,ro "$target"
        fi
    fi
}

mount_system() {
    mount_once "$ROOT/proc" -t proc proc
    mount_once "$ROOT/sys" -t sysfs -o ro sysfs
    mount_once "$ROOT/dev" --rbind /dev
    mount --make-rslave "$ROOT/dev"
}

mount_user_dirs() {
    # Parents before children, in case one of these lies inside another.
    local dir
    while IFS= read -r dir; do
        case $dir in
            "$RUSTUP_HOME_DIR") bind_once "$dir" ro ;;
            *) bind_once "$dir" ;;
        esac
    done < <(printf '%s\n' "$REPO" "$CARGO_HOME_DIR" "$RUSTUP_HOME_DIR" | sort -u)
}

cleanup() {
    local rc=$?
    trap - EXIT INT TERM HUP
    unmount_all
    exit "$rc"
}

# --- one run at a time per chroot, in a private mount namespace --------------

if [[ -z ${EMBREE4_INNER:-} ]]; then
    lock_dir=/run/lock
    [[ -d $lock_dir && -w $lock_dir ]] || lock_dir=/tmp
    exec 9>"$lock_dir/embree4-chroot.$(printf '%s' "$ROOT" | md5sum | cut -c1-12).lock"
    if ! flock -n 9; then
        log "waiting for another run using $ROOT..."
        flock 9
    fi
    # Mounts left by a run that was killed before its trap ran.
    if [[ -n $(mounts_under_root) ]]; then
        log "unmounting what an interrupted run left under $ROOT"
        unmount_all
    fi
    if [[ ${EMBREE4_NO_UNSHARE:-} != 1 ]] \
        && unshare --mount --propagation private true 2>/dev/null; then
        # The lock (fd 9) stays held across exec.
        EMBREE4_INNER=1 exec unshare --mount --propagation private bash "$0" "$@"
    fi
    log "mounting in the host's mount namespace (no private one: EMBREE4_NO_UNSHARE=1 or no unshare)"
fi
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
trap 'exit 129' HUP

# in_chroot CMD...: runs CMD as root in the chroot with a clean environment.
in_chroot() {
    chroot "$ROOT" /usr/bin/env -i \
        PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
        HOME=/root LANG=C.UTF-8 DEBIAN_FRONTEND=noninteractive \
        "${proxy_env[@]}" "$@" </dev/null
}

proxy_env=()
for var in http_proxy https_proxy no_proxy HTTP_PROXY HTTPS_PROXY NO_PROXY; do
    if [[ -n ${!var:-} ]]; then proxy_env+=("$var=${!var}"); fi
done

# Host CA certificates (e.g. of an HTTPS-intercepting proxy) into the chroot,
# so cargo can fetch crates; apt over http needs none.
sync_ca_certificates() {
    local crt changed=
    mkdir -p "$ROOT/usr/local/share/ca-certificates"
    shopt -s nullglob
    for crt in /usr/local/share/ca-certificates/*.crt; do
        if ! cmp -s "$crt" "$ROOT$crt"; then
            cp "$crt" "$ROOT$crt"
            changed=1
        fi
    done
    shopt -u nullglob
    if [[ -n $changed || ! -s $ROOT/etc/ssl/certs/ca-certificates.crt ]]; then
        log "updating CA certificates in the chroot"
        # (Its "rehash: warning: skipping ca-certificates.crt" is expected.)
        in_chroot update-ca-certificates >/dev/null 2>&1 \
            || die "update-ca-certificates failed in the chroot"
    fi
}

# --- the chroot ---------------------------------------------------------------

want_stamp=$(printf '%s\n' "suite=$SUITE" "packages=${PACKAGES[*]}")

# Deletes a partly made (or to be rebuilt) chroot, never anything mounted
# under it, nor a directory this script did not make.
remove_chroot() {
    [[ -e $ROOT ]] || return 0
    unmount_all
    [[ -z $(mounts_under_root) ]] || die "still mounted under $ROOT; not deleting it"
    if [[ -n $(ls -A "$ROOT") && ! -e $ROOT/$MARKER_NAME ]]; then
        die "$ROOT exists but was not made by this script; remove it yourself"
    fi
    log "removing $ROOT"
    rm -rf --one-file-system "$ROOT"
}

setup_chroot() {
    local start=$SECONDS
    if [[ ${EMBREE4_REBUILD:-} == 1 || ! -e $ROOT/$BOOTSTRAPPED_NAME ]]; then
        remove_chroot
        if ! command -v debootstrap >/dev/null; then
            log "installing debootstrap on the host"
            export DEBIAN_FRONTEND=noninteractive
            apt-get install -y -q debootstrap </dev/null >/dev/null \
                || { apt-get update -q </dev/null >/dev/null \
                     && apt-get install -y -q debootstrap </dev/null >/dev/null; } \
                || die "could not install debootstrap"
        fi
        mkdir -p "$ROOT"
        touch "$ROOT/$MARKER_NAME"
        log "creating Debian 13 ($SUITE) chroot at $ROOT (about a minute)..."
        local debootstrap_log=$ROOT/.embree4-debootstrap.log
        if ! debootstrap --variant=minbase "$SUITE" "$ROOT" "$MIRROR" \
                </dev/null >"$debootstrap_log" 2>&1; then
            tail -n 30 "$debootstrap_log" >&2
            [[ -f $ROOT/debootstrap/debootstrap.log ]] \
                && tail -n 30 "$ROOT/debootstrap/debootstrap.log" >&2
            die "debootstrap failed (full log: $debootstrap_log)"
        fi
        touch "$ROOT/$BOOTSTRAPPED_NAME"
    fi
    mount_system
    cp -L /etc/resolv.conf "$ROOT/etc/resolv.conf" 2>/dev/null || true
    log "installing Embree 4 and clang in the chroot..."
    local apt_log=$ROOT/.embree4-apt.log
    if ! { in_chroot dpkg --configure -a \
           && in_chroot apt-get update -q \
           && in_chroot apt-get install -y -q --no-install-recommends "${PACKAGES[@]}" \
           && in_chroot apt-get clean; } >"$apt_log" 2>&1; then
        tail -n 30 "$apt_log" >&2
        die "installing packages in the chroot failed (full log: $apt_log)"
    fi
    sync_ca_certificates
    [[ -f $ROOT/usr/include/embree4/rtcore.h ]] || die "no /usr/include/embree4 in the chroot"
    printf '%s\n' "$want_stamp" >"$ROOT/$STAMP_NAME"
    log "chroot ready in $((SECONDS - start)) s"
}

if [[ ${EMBREE4_REBUILD:-} != 1 && -f $ROOT/$STAMP_NAME \
      && $(cat "$ROOT/$STAMP_NAME") == "$want_stamp" ]]; then
    log "reusing chroot at $ROOT"
    mount_system
    cp -L /etc/resolv.conf "$ROOT/etc/resolv.conf" 2>/dev/null || true
    sync_ca_certificates
else
    rm -f "$ROOT/$STAMP_NAME"
    setup_chroot
fi
mount_user_dirs

# --- the tests ------------------------------------------------------------------

# Environment for cargo inside: a clean one, plus what steers cargo/rustc.
cargo_env=(
    HOME="$USER_HOME"
    PATH="$CARGO_HOME_DIR/bin:/usr/local/bin:/usr/bin:/bin"
    CARGO_HOME="$CARGO_HOME_DIR"
    RUSTUP_HOME="$RUSTUP_HOME_DIR"
    CARGO_TARGET_DIR="$TARGET_DIR"
    LANG=C.UTF-8
    "${proxy_env[@]}"
)
for var in CI TERM RUSTUP_TOOLCHAIN RUSTUP_AUTO_INSTALL RUSTFLAGS RUSTDOCFLAGS \
           RUST_BACKTRACE RUST_LOG RUST_TEST_THREADS CARGO_TERM_COLOR \
           CARGO_INCREMENTAL CARGO_BUILD_JOBS CARGO_NET_OFFLINE; do
    if [[ -n ${!var:-} ]]; then cargo_env+=("$var=${!var}"); fi
done
userspec=()
if [[ -n $RUN_AS ]]; then userspec=(--userspec="$RUN_AS"); fi

run_inside() {
    log "running in the chroot: $*"
    chroot "${userspec[@]}" "$ROOT" /usr/bin/env -i -C "$REPO" "${cargo_env[@]}" "$@"
}

embree=$(chroot "$ROOT" dpkg-query -W -f '${Version}' libembree-dev 2>/dev/null || true)
log "Embree ${embree:-?} from Debian $(cat "$ROOT/etc/debian_version"); target dir $TARGET_DIR"
run_inside cargo test --all-targets
if [[ $# -gt 0 ]]; then
    run_inside "$@"
fi
log "all passed against Embree 4"
