#!/usr/bin/env bash
# Three robots and an operator on one machine, standing in for four hosts: the robots
# bind 127.0.0.1, 127.0.0.2 and 127.0.0.3 (all loopback on Linux). Starts each robot as
# its own process, runs mission.yaml from the operator's config to its end, stops
# everything, and exits 0 only if the mission succeeded.
#
#   examples/team/run-local.sh            # from anywhere; BTCAP=... to pick the command
#   BTCAP_TEAM_LOGS=DIR examples/team/run-local.sh   # also keep each robot's log in DIR
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
if [[ -n "${BTCAP:-}" ]]; then
    read -r -a btcap <<< "$BTCAP"
elif [[ -x "$root/.venv/bin/btcap" ]]; then
    btcap=("$root/.venv/bin/btcap")
else
    btcap=(python3 -m btcap)
fi

work="$(mktemp -d "${TMPDIR:-/tmp}/btcap-team.XXXXXX")"
pids=()
cleanup() {
    for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
    for pid in "${pids[@]}"; do
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
        kill -KILL "$pid" 2>/dev/null || true
        wait "$pid" 2>/dev/null || true
    done
    if [[ -n "${BTCAP_TEAM_LOGS:-}" ]]; then
        mkdir -p "$BTCAP_TEAM_LOGS" && cp "$work"/*.log "$BTCAP_TEAM_LOGS"/ 2>/dev/null || true
    fi
    rm -rf "$work"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# Keys for every robot, in ZeroMQ's certificate format: the configs name them through
# $BTCAP_KEYS, and every link of the team is encrypted and authenticated with them.
export BTCAP_KEYS="$work/keys"
mkdir -p "$BTCAP_KEYS"
for robot in alpha beta gamma; do
    "${btcap[@]}" keys new "$robot" --role robot --dir "$BTCAP_KEYS" > /dev/null
done
"${btcap[@]}" keys new operator --role operator --dir "$BTCAP_KEYS" > /dev/null
echo "keys written to $BTCAP_KEYS"

for robot in alpha beta gamma; do
    "${btcap[@]}" agent "$here/$robot.yaml" > "$work/$robot.out" 2> "$work/$robot.log" &
    pids+=("$!")
done

# Each agent prints one line once it listens.
robots=(alpha beta gamma)
for i in "${!robots[@]}"; do
    robot="${robots[$i]}"
    for _ in $(seq 300); do
        grep -q "listening" "$work/$robot.out" 2>/dev/null && break
        kill -0 "${pids[$i]}" 2>/dev/null || break
        sleep 0.1
    done
    if ! grep -q "listening" "$work/$robot.out" 2>/dev/null; then
        echo "agent $robot did not start:" >&2
        cat "$work/$robot.log" >&2
        exit 1
    fi
    cat "$work/$robot.out"
done

# The operator knows only alpha; alpha, beta and gamma each know one other robot.
"${btcap[@]}" team status --config "$here/operator.yaml" --wait 10 | tee "$work/status.out"
if ! grep -q "3 member(s)" "$work/status.out"; then
    echo "the operator did not meet all three robots through alpha" >&2
    exit 1
fi

status=0
"${btcap[@]}" mission run "$here/mission.yaml" --config "$here/operator.yaml" --timeout 60 \
    || status=$?
exit "$status"
