#!/bin/sh
# What the system-level tests need, set up when it is missing (`make system-deps`, run by `make test`):
#   - a Docker engine and debootstrap, for tests/app/test_container.py (the image built and run; without a
#     container registry its base is made from Debian's packages by ../shared/tools/local-python-base.sh);
#   - Debian's chromium with a font, for the browser test.
# Idempotent: installs only what is missing, starts dockerd only when no engine answers. Only as root on a
# system with apt-get; elsewhere it says what it skips and the tests concerned skip with a reason.
# It never fails: every problem is reported on stderr and the script exits 0.
LOG_DIR=/tmp/backlash-system-deps
DOCKERD_LOG="$LOG_DIR/dockerd.log"

say() { echo "system-deps: $*" >&2; }

if [ "$(id -u)" -ne 0 ] || ! command -v apt-get >/dev/null 2>&1; then
    say "not root on a system with apt-get: skipping docker.io, debootstrap and chromium (their tests skip if absent)"
    exit 0
fi

missing=""
command -v dockerd >/dev/null 2>&1 || missing="$missing docker.io"
command -v debootstrap >/dev/null 2>&1 || missing="$missing debootstrap"
command -v chromium >/dev/null 2>&1 || missing="$missing chromium"
dpkg-query -W -f='${Status}' fonts-dejavu-core 2>/dev/null | grep -q 'ok installed' || missing="$missing fonts-dejavu-core"

if [ -n "$missing" ]; then
    mkdir -p "$LOG_DIR"
    say "installing$missing (log: $LOG_DIR/apt.log)"
    # one apt-get call for all of them; wait for another apt or dpkg run instead of failing on its lock
    if ! { apt-get -o DPkg::Lock::Timeout=300 update \
        && DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=300 install -y --no-install-recommends $missing; } \
        >"$LOG_DIR/apt.log" 2>&1; then
        say "apt-get failed (last lines below); the tests that need$missing skip"
        tail -n 5 "$LOG_DIR/apt.log" >&2
    fi
fi

engine_answers() { timeout 20 docker info >/dev/null 2>&1; }

if ! command -v docker >/dev/null 2>&1 || ! command -v dockerd >/dev/null 2>&1; then
    say "no docker or dockerd command: the container test skips"
    exit 0
fi
if engine_answers; then
    exit 0
fi
mkdir -p "$LOG_DIR"
say "no Docker engine answers: starting dockerd in the background (log: $DOCKERD_LOG)"
# its own session, so that it outlives make and no terminal signal reaches it
setsid dockerd >>"$DOCKERD_LOG" 2>&1 </dev/null &
i=0
while [ "$i" -lt 60 ]; do
    if engine_answers; then
        say "Docker engine up after ${i} s"
        exit 0
    fi
    sleep 1
    i=$((i + 1))
done
say "the Docker engine did not answer within 60 s (last lines of $DOCKERD_LOG below): the container test skips"
tail -n 5 "$DOCKERD_LOG" >&2
exit 0
