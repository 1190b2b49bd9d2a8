"""The text table :mod:`bench.speed.auction` prints."""

from __future__ import annotations

from typing import Any

__all__ = ["table", "to_floor"]


def to_floor(
    rounds: dict[str, Any], floor_ms: dict[str, Any], crowded: str, reference: str
) -> dict[str, Any]:
    """btcap's rows (p50) over the floor's (per security, variant, row); the crowded row
    over the floor's row of ``reference`` bidders (the floor has no idle teammates)."""
    return {
        security: {
            variant: {
                label: row["p50"] / by_n[reference if label == crowded else label]["p50"]
                for label, row in rounds[security].items()
                if label != "isolated"
            }
            for variant, by_n in floor_ms[security].items()
        }
        for security in rounds
    }


def _rows(data: dict[str, Any]) -> list[str]:
    """Row labels in order: each size, the crowded row after the 10 row (older results
    have none)."""
    labels = [str(n) for n in data["setup"]["bidders"]]
    crowded = data["setup"].get("crowded_row")
    if crowded in data["round_ms"]["zmq_tcp"]:
        labels.insert(labels.index(crowded.split("_")[0]) + 1, crowded)
    return labels


def _floor_p50(data: dict[str, Any], security: str, label: str, variant: str) -> float:
    floor = data.get("floor_ms", {}).get(security, {}).get(variant, {})
    row = floor.get(label.split("_")[0])
    return float("nan") if row is None else float(row["p50"])


def table(data: dict[str, Any], window_s: float) -> str:
    """The benchmark's figures as the text it prints."""
    rounds, cpu = data["round_ms"], data["round_cpu_ms"]
    teams = data["setup"].get("teams", {})
    lines = [
        "auction round, call for bids -> accepted award (ms); cpu = CPU ms per round; floor ="
        " the same round hand-written without btcap (blocking / asyncio), same run",
        f"{'bidders':>8} {'team':>4} | {'inproc p50':>10} {'p99':>7} {'cpu':>5} | "
        f"{'tcp p50':>7} {'p99':>7} {'cpu here':>8} {'bidders':>7} | "
        f"{'floor blk':>9} {'aio':>6} {'/blk':>5} {'/aio':>5}",
    ]
    for k in _rows(data):
        a, b = rounds["inproc"][k], rounds["zmq_tcp"][k]
        ca, cb = cpu["inproc"][k], cpu["zmq_tcp"][k]
        blk, aio = (_floor_p50(data, "zmq_tcp", k, v) for v in ("blocking", "asyncio"))
        lines.append(
            f"{k.replace('_of_', '/'):>8} {teams.get(k, 51):>4} | {a['p50']:>10.3f} "
            f"{a['p99']:>7.3f} {ca['this_process']:>5.2f} | {b['p50']:>7.3f} {b['p99']:>7.3f} "
            f"{cb['this_process']:>8.2f} {cb['bidder_processes']:>7.2f} | {blk:>9.3f} "
            f"{aio:>6.3f} {b['p50'] / blk:>5.2f} {b['p50'] / aio:>5.2f}"
        )
    setup = data["setup"]
    if setup.get("crowded_row"):
        lines.append(
            "team = the origin and its bidders, one team per row (a deployment: one robot per"
            " computer), but 10/51: the first 10 of the team of 51, a crowded host"
        )
    ok = "yes" if data["early_close"]["all"] else "NO"
    lines.append(
        f"every round closed early: {ok} (window {window_s} s); bidders over tcp in "
        f"{setup['bidder_processes']} processes; load average "
        f"{setup['load_average'][0]:.1f} -> {setup['load_average'][1]:.1f}"
    )
    k = str(data["round_to_ask"]["bidders"])
    lines.append(
        f"{k} bidders, p50 / p90 (ms): back to back (bursts of {setup['burst_rounds']}) "
        + ", ".join(
            f"{name} {rounds[name][k]['p50']:.3f} / {rounds[name][k]['p90']:.3f}"
            for name in ("inproc", "zmq_tcp", "zmq_tcp_curve")
        )
    )
    lines.append(
        f"{k} bidders, one round every {setup['isolated_gap_s'] * 1e3:.0f} ms, p50 / p90 (ms): "
        + ", ".join(
            f"{name} {rounds[name]['isolated']['p50']:.3f} / {rounds[name]['isolated']['p90']:.3f}"
            for name in ("inproc", "zmq_tcp", "zmq_tcp_curve")
        )
    )
    a, r = data["ask_us"], data["round_to_ask"]
    lines.append(
        f"same run, {r['bidders']} bidders over tcp: round p50 = "
        f"{r['round_p50_over_tcp_ask_p50']:.1f}x a tcp ask (p50 {a['zmq_tcp_ask']['p50']:.1f} us)"
        f" = {r['round_p50_over_floor_p50']:.1f}x blocking pyzmq's round trip "
        f"(p50 {a['raw_zmq_tcp_blocking']['p50']:.1f} us)"
    )
    lines.append(_verdict(data))
    lines.append("")
    lines.append(_curve_table(data))
    t, f = data["remote_tick_ms"], data["failover_s"]
    lines.append(f"remote tick round trip (tcp): p50 {t['p50']:.3f} ms, p99 {t['p99']:.3f} ms")
    lines.append(
        f"fail-over at speed-up 1: p50 {f['p50']:.3f} s, max {f['max']:.3f} s "
        f"({f['repeats']} kills)"
    )
    return "\n".join(lines)


def _verdict(data: dict[str, Any]) -> str:
    """DESIGN's budget (10 bidders over tcp, p50 <= 1 ms) against btcap and the floor."""
    k = str(data["round_to_ask"]["bidders"])
    ours = data["round_ms"]["zmq_tcp"][k]["p50"]
    floor = min(_floor_p50(data, "zmq_tcp", k, v) for v in ("blocking", "asyncio"))
    if floor != floor:  # no floor in these results
        return f"budget: {k} bidders over tcp p50 {ours:.3f} ms (<= 1 ms wanted)"
    met = "met" if ours <= 1.0 else "NOT met"
    above = (
        f"the floor itself is ABOVE 1 ms on this machine now ({floor:.3f} ms)"
        if floor > 1.0
        else f"the floor takes {floor:.3f} ms"
    )
    return (
        f"budget, {k} bidders over tcp p50 <= 1 ms: {met} ({ours:.3f} ms, "
        f"{ours / floor:.2f}x the faster floor); {above}"
    )


def _curve_table(data: dict[str, Any]) -> str:
    rounds, cpu = data["round_ms"], data["round_cpu_ms"]
    lines = [
        "auction round over tcp, plain vs CURVE (ms; cpu = here + bidders, CPU ms per round;"
        " /floor: CURVE over the faster CURVE floor)",
        f"{'bidders':>8} | {'plain p50':>9} {'p99':>7} {'cpu':>6} | "
        f"{'CURVE p50':>9} {'p99':>7} {'cpu':>6} | {'ratio p50':>9} {'p99':>5} {'cpu':>5} | "
        f"{'/floor':>6}",
    ]
    for k in _rows(data):
        a, b = rounds["zmq_tcp"][k], rounds["zmq_tcp_curve"][k]
        ca, cb = (
            c[k]["this_process"] + c[k]["bidder_processes"]
            for c in (cpu["zmq_tcp"], cpu["zmq_tcp_curve"])
        )
        floor = min(_floor_p50(data, "zmq_tcp_curve", k, v) for v in ("blocking", "asyncio"))
        lines.append(
            f"{k.replace('_of_', '/'):>8} | {a['p50']:>9.3f} {a['p99']:>7.3f} {ca:>6.2f} | "
            f"{b['p50']:>9.3f} {b['p99']:>7.3f} {cb:>6.2f} | "
            f"{b['p50'] / a['p50']:>9.2f} {b['p99'] / a['p99']:>5.2f} {cb / ca:>5.2f} | "
            f"{b['p50'] / floor:>6.2f}"
        )
    return "\n".join(lines)
