#!/usr/bin/env bash
# Start a throwaway PostgreSQL cluster on a loopback port and print its SQLAlchemy URL.
#
#   export BIOPLAN_TEST_POSTGRES_URL="$(scripts/ci_postgres.sh)"
#   .venv/bin/pytest tests/db tests/api        # the same tests, now also on PostgreSQL
#   scripts/ci_postgres.sh stop                 # stop it (or leave it: it lives in /tmp)
#
# Installs Debian's `postgresql` package when no server binaries are found (needs root).
# The cluster lives in $BIOPLAN_PG_DIR (default /tmp/bioplan-pg), trusts local connections,
# listens on 127.0.0.1 only, and runs as the `postgres` user when this script runs as root.
# Everything but the URL goes to stderr.
set -euo pipefail

DIR="${BIOPLAN_PG_DIR:-/tmp/bioplan-pg}"
DB="${BIOPLAN_PG_DB:-bioplan_test}"
USER_NAME="bioplan"

find_bin() {
    ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1
}

as_owner() {
    if [ "$(id -u)" = 0 ]; then
        runuser -u postgres -- "$@"
    else
        "$@"
    fi
}

BIN="$(find_bin)"
if [ "${1:-}" = "stop" ]; then
    if [ -n "$BIN" ] && [ -f "$DIR/data/postmaster.pid" ]; then
        as_owner "$BIN/pg_ctl" -D "$DIR/data" -m fast -w stop >&2
    fi
    exit 0
fi

if [ -z "$BIN" ]; then
    echo "installing PostgreSQL from Debian's packages" >&2
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >&2
    apt-get install -y -qq postgresql >&2
    BIN="$(find_bin)"
fi

# Reuse a cluster only when its server answers: a pid file can outlive the machine's restart.
if [ -f "$DIR/data/postmaster.pid" ] && [ -f "$DIR/port" ] \
        && as_owner "$BIN/pg_ctl" -D "$DIR/data" status >/dev/null 2>&1; then
    PORT="$(cat "$DIR/port")"
else
    PORT="${BIOPLAN_PG_PORT:-$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')}"
    rm -rf "$DIR"
    mkdir -p "$DIR"
    if [ "$(id -u)" = 0 ]; then
        id postgres >/dev/null 2>&1 || useradd --system --no-create-home postgres
        chown postgres "$DIR"
    fi
    as_owner "$BIN/initdb" -D "$DIR/data" -A trust -U "$USER_NAME" -E UTF8 >/dev/null
    as_owner "$BIN/pg_ctl" -D "$DIR/data" -l "$DIR/server.log" -w \
        -o "-c listen_addresses=127.0.0.1 -p $PORT -k $DIR -c fsync=off" start >&2
    echo "$PORT" > "$DIR/port"
fi

if ! as_owner "$BIN/psql" -h 127.0.0.1 -p "$PORT" -U "$USER_NAME" -d postgres -tAc \
        "SELECT 1 FROM pg_database WHERE datname = '$DB'" | grep -q 1; then
    as_owner "$BIN/createdb" -h 127.0.0.1 -p "$PORT" -U "$USER_NAME" "$DB"
fi
echo "postgresql+psycopg://$USER_NAME@127.0.0.1:$PORT/$DB"
