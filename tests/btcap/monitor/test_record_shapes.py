"""Events a recording holds are checked as it is read for what the MCAP channels and the
Foxglove scene read of them: a hand-made or damaged file is refused with one line naming
the line, the event's kind and the field, never by a traceback halfway through
``--to-mcap`` or a replay to Foxglove."""

from __future__ import annotations

from pathlib import Path

import pytest

from btcap.cli import main
from btcap.monitor.record import RecordError, read_record

HEAD = '{"format":"btcap-monitor","version":1}\n'

#: An event each, and what the line says of it.
BAD = {
    "pose-not-a-pair": ('{"t":1,"k":"world","poses":{"r1":"oops"}}', "Expected `array`"),
    "pose-of-one": ('{"t":1,"k":"world","poses":{"r1":[1]}}', "of length 2"),
    "robot-without-task": (
        '{"t":1,"k":"world","robots":{"r1":{"up":true}}}',
        "missing required field `task`",
    ),
    "object-without-place": ('{"t":1,"k":"world","objects":[{"id":1}]}', "field `x`"),
    "robots-not-a-map": ('{"t":1,"k":"world","robots":"x"}', "at `$.robots`"),
    "map-without-rows": ('{"t":1,"k":"map"}', "field `rows`"),
    "map-of-no-size": (
        '{"t":1,"k":"map","rows":["#."],"cell_m":0,"start":[0,0],"decon":[1,1]}',
        "`$.cell_m`",
    ),
    "run-end-without-result": ('{"t":1,"k":"run","phase":"end","execution":"e"}', "`result`"),
    "auction-phase": (
        '{"t":1,"k":"auction","phase":"shut","id":"a","execution":"e","bids":[],"winner":null}',
        "`$.phase`",
    ),
    "bid-without-cost": (
        '{"t":1,"k":"auction","phase":"close","id":"a","execution":"e","bids":[["r"]],'
        '"winner":"r"}',
        "`$.bids[0]`",
    ),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_a_bad_event_is_refused_naming_its_line_and_field(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    event, said = BAD[name]
    path = tmp_path / "run.jsonl"
    path.write_text(HEAD + '{"t":0,"k":"robot","robot":"r1"}\n' + event + "\n")
    assert main(["replay", str(path), "--to-mcap", str(tmp_path / "out.mcap")]) == 2
    err = capsys.readouterr().err
    kind = event.split('"k":"')[1].split('"')[0]
    assert err.startswith(f"btcap: error: {path}:3: a {kind!r} event: ")
    assert said in err
    assert err.count("\n") == 1
    assert not (tmp_path / "out.mcap").exists()


def test_a_whole_last_line_that_is_not_json_is_refused_not_taken_as_cut(
    tmp_path: Path,
) -> None:
    """The recorder ends every line: a last line that has its end is not a cut one."""
    path = tmp_path / "run.jsonl"
    path.write_text(HEAD + '{"t":0,"k":"robot","robot":"r1"}\n{"t":1,"k":"robot",}\n')
    with pytest.raises(RecordError, match=r"run\.jsonl:3: not a JSON object"):
        read_record(path)
