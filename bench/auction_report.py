"""The text table :mod:`bench.auction` prints."""

from __future__ import annotations

from typing import Any

__all__ = ["table"]


def table(data: dict[str, Any], window_s: float) -> str:
    """The benchmark's figures as the text it prints."""
    rounds, cpu = data["round_ms"], data["round_cpu_ms"]
    lines = [
        "auction round, call for bids -> accepted award (ms); cpu = CPU ms per round",
        f"{'bidders':>7} | {'inproc p50':>10} {'p99':>7} {'cpu':>6} | "
        f"{'tcp p50':>7} {'p99':>7} {'cpu here':>8} {'cpu bidders':>11}",
    ]
    for n in data["setup"]["bidders"]:
        k = str(n)
        a, b = rounds["inproc"][k], rounds["zmq_tcp"][k]
        ca, cb = cpu["inproc"][k], cpu["zmq_tcp"][k]
        lines.append(
            f"{n:>7} | {a['p50']:>10.3f} {a['p99']:>7.3f} {ca['this_process']:>6.2f} | "
            f"{b['p50']:>7.3f} {b['p99']:>7.3f} {cb['this_process']:>8.2f} "
            f"{cb['bidder_processes']:>11.2f}"
        )
    setup = data["setup"]
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
    lines.append("")
    lines.append(_curve_table(data))
    t, f = data["remote_tick_ms"], data["failover_s"]
    lines.append(f"remote tick round trip (tcp): p50 {t['p50']:.3f} ms, p99 {t['p99']:.3f} ms")
    lines.append(
        f"fail-over at speed-up 1: p50 {f['p50']:.3f} s, max {f['max']:.3f} s "
        f"({f['repeats']} kills)"
    )
    return "\n".join(lines)


def _curve_table(data: dict[str, Any]) -> str:
    rounds, cpu = data["round_ms"], data["round_cpu_ms"]
    lines = [
        "auction round over tcp, plain vs CURVE (ms; cpu = here + bidders, CPU ms per round)",
        f"{'bidders':>7} | {'plain p50':>9} {'p99':>7} {'cpu':>6} | "
        f"{'CURVE p50':>9} {'p99':>7} {'cpu':>6} | {'ratio p50':>9} {'p99':>5} {'cpu':>5}",
    ]
    for n in data["setup"]["bidders"]:
        k = str(n)
        a, b = rounds["zmq_tcp"][k], rounds["zmq_tcp_curve"][k]
        ca, cb = (
            c[k]["this_process"] + c[k]["bidder_processes"]
            for c in (cpu["zmq_tcp"], cpu["zmq_tcp_curve"])
        )
        lines.append(
            f"{n:>7} | {a['p50']:>9.3f} {a['p99']:>7.3f} {ca:>6.2f} | "
            f"{b['p50']:>9.3f} {b['p99']:>7.3f} {cb:>6.2f} | "
            f"{b['p50'] / a['p50']:>9.2f} {b['p99'] / a['p99']:>5.2f} {cb / ca:>5.2f}"
        )
    return "\n".join(lines)
