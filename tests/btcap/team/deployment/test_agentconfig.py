"""Agent configuration files: every bad field is named, good files build what they say."""

from __future__ import annotations

from pathlib import Path

import msgspec
import msgspec.inspect
import pytest

from btcap.bt.registry import default_registry
from btcap.sim.world.messages import SIM_MESSAGES
from btcap.team.deployment.agentconfig import (
    AgentConfigError,
    Allocation,
    FileTiming,
    Timing,
    load_agent_file,
)
from btcap.team.runtime.agent import AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports.newcomers import LINKS_PER_PEER
from btcap.transports.security import write_key_pair

ROOT = Path(__file__).resolve().parents[4]
CAPS = ROOT / "examples" / "capabilities"
TEAM = ROOT / "examples" / "team"

GOOD = f"""\
btcap: 1
robot: alpha
capabilities:
  interfaces: [{CAPS / "interfaces.yaml"}]
  implementations: [{CAPS / "greet.yaml"}]
network:
  bind: tcp://127.0.0.1:*
  seeds: [{{robot: beta, endpoint: "tcp://127.0.0.2:7102"}}]
timing: {{tick_hz: 20, heartbeat_s: 0.2, failure_timeout_s: 2.0, lease_s: 3.0, speedup: 2}}
allocation: {{rebid_on_join: 0.25}}
"""


BIND = "bind: tcp://127.0.0.1:*"


def _write(tmp_path: Path, text: str, name: str = "robot.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_good_file_gives_the_robot_its_settings(tmp_path: Path) -> None:
    config = load_agent_file(_write(tmp_path, GOOD))
    assert config.robot == "alpha"
    assert config.seeds == {"beta": "tcp://127.0.0.2:7102"}
    assert config.spec.timing.speedup == 2
    assert config.agent_config() == AgentConfig(
        tick_hz=20, heartbeat_s=0.2, failure_timeout_s=2.0, lease_s=3.0, rebid_on_join=0.25
    )
    registry = default_registry(plugins=False)
    interfaces, impls = config.load_capabilities(registry)
    assert [i.name for i in interfaces] == ["Greet"]
    assert [i.name for i in impls] == ["greet-by-log"]
    assert "Greet" in registry  # mission trees can use the capability node type


def test_the_blocks_hold_exactly_the_fields_of_agent_config() -> None:
    """AgentConfig repeats the names of the file blocks (msgspec Structs have one base);
    a setting added to one but not the other, or with another type or default, fails."""
    flat = msgspec.inspect.type_info(AgentConfig).fields
    blocks = [f for b in (Timing, Allocation) for f in msgspec.inspect.type_info(b).fields]
    assert sorted(f.name for f in blocks) == sorted(f.name for f in flat)
    by_name = {f.name: f for f in flat}
    for f in blocks:
        assert (f.type, f.default) == (by_name[f.name].type, by_name[f.name].default), f.name
    file_timing = {f.name for f in msgspec.structs.fields(FileTiming)}
    assert file_timing - {f.name for f in msgspec.structs.fields(Timing)} == {"speedup"}


def test_paths_are_relative_to_the_file_and_key_paths_expand_the_environment(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("BTCAP_KEYS", raising=False)
    with pytest.raises(AgentConfigError, match=r"keys.secret: .*BTCAP_KEYS.*variable is not set"):
        load_agent_file(TEAM / "alpha.yaml")
    for robot in ("alpha", "beta"):
        write_key_pair(tmp_path, robot)
    monkeypatch.setenv("BTCAP_KEYS", str(tmp_path))
    config = load_agent_file(TEAM / "alpha.yaml")
    assert config.spec.capabilities.interfaces == [CAPS / "interfaces.yaml"]
    assert config.spec.keys is not None
    assert config.spec.keys.secret == tmp_path / "alpha.key_secret"


@pytest.mark.parametrize(
    ("old", "new", "needle"),
    [
        ("btcap: 1", "btcap: 2", "btcap: version 2"),
        ("robot: alpha", "robot: a/b", "robot:"),
        ("robot: alpha", "robot: 7", "robot: Expected `str`"),
        ("robot: alpha\n", "", "missing required field `robot`"),
        ("btcap: 1\n", "colour: red\nbtcap: 1\n", "unknown field `colour`"),
        ("  bind: tcp", "  port: 1\n  bind: tcp", "network: Object contains unknown field `port`"),
        ("bind: tcp://127.0.0.1:*", "bind: udp://x:1", "network.bind:"),
        ("bind: tcp://127.0.0.1:*", "bind: tcp://0.0.0.0:7000", "network.advertise: required"),
        (
            "bind: tcp://127.0.0.1:*",
            "bind: tcp://0.0.0.0:7000\n  advertise: tcp://10.0.0.1:*",
            "network.advertise:",
        ),
        ("robot: beta,", "robot: alpha,", "network.seeds[0].robot: 'alpha' is this robot"),
        ("robot: beta,", "robot: '*',", "network.seeds[0].robot"),
        ('"tcp://127.0.0.2:7102"', '"127.0.0.2:7102"', "network.seeds[0].endpoint"),
        # libzmq would wrap these round to another port: refused, not silently moved
        ("bind: tcp://127.0.0.1:*", "bind: tcp://127.0.0.1:99999", "network.bind: 'tcp://"),
        ('"tcp://127.0.0.2:7102"', '"tcp://127.0.0.2:70000"', "port '70000': expected 0 to"),
        ('"tcp://127.0.0.2:7102"', '"tcp://127.0.0.2:*"', "network.seeds[0].endpoint"),
        (
            '"tcp://127.0.0.2:7102"}]',
            '"tcp://h:1"}, {robot: b}]',
            "network.seeds[1]: Object missing required field `endpoint`",
        ),
        ("endpoint:", "ednpoint:", "network.seeds[0]: Object contains unknown field `ednpoint`"),
        # the transport's guards against silent connections
        (BIND, f"{BIND}\n  hello_timeout_s: 0", "network.hello_timeout_s: Expected `float` > 0"),
        (BIND, f"{BIND}\n  hello_timeout_s: soon", "network.hello_timeout_s: Expected `float`"),
        (BIND, f"{BIND}\n  hello_timeout_s: .inf", "network.hello_timeout_s"),
        (BIND, f"{BIND}\n  max_newcomers: 0", "network.max_newcomers: Expected `int` >= 1"),
        (BIND, f"{BIND}\n  links_per_peer: 1", "network.links_per_peer: Expected `int` >= 2"),
        (BIND, f"{BIND}\n  links_per_peer: 2.5", "network.links_per_peer: Expected `int`"),
        ("tick_hz: 20", "tick_hz: 0", "timing.tick_hz: Expected `float` > 0.0"),
        ("tick_hz: 20", "tick_hz: fast", "timing.tick_hz: Expected `float`, got `str`"),
        ("tick_hz: 20", "tick_hz: 20, tick_rate: 3", "timing: Object contains unknown field"),
        ("failure_timeout_s: 2.0", "failure_timeout_s: 0.1", "timing.failure_timeout_s: must"),
        ("lease_s: 3.0", "lease_s: 3.0, keepalive_s: 4", "timing.keepalive_s: must"),
        ("rebid_on_join: 0.25", "rebid_on_join: 2", "allocation.rebid_on_join"),
        ("interfaces.yaml", "nope.yaml", "capabilities.interfaces[0]:"),
        ("greet.yaml", "nope.yaml", "capabilities.implementations[0]:"),
        ("implementations:", "implementation:", "capabilities: Object contains unknown field"),
        ("allocation:", "keys: {secret: a.key_secret, trusted: t}\nallocation:", "keys.secret: "),
        (
            "allocation:",
            "keys: {secret: a.key_secret}\nallocation:",
            "keys: Object missing required",
        ),
        ("allocation:", "keys: {public: a.key}\nallocation:", "keys: Object contains unknown"),
    ],
)
def test_bad_fields_are_named_with_the_file(
    tmp_path: Path, old: str, new: str, needle: str
) -> None:
    assert old in GOOD
    path = _write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(AgentConfigError) as err:
        load_agent_file(path)
    assert str(err.value).startswith(f"{path}: ")
    assert needle in str(err.value)


def test_missing_key_files_are_named(tmp_path: Path) -> None:
    text = GOOD + "keys: {secret: keys/alpha.key_secret, trusted: keys}\n"
    with pytest.raises(AgentConfigError, match=r"keys\.secret: .*alpha\.key_secret: no such file"):
        load_agent_file(_write(tmp_path, text))
    (tmp_path / "keys").mkdir()
    (tmp_path / "keys" / "alpha.key_secret").write_text("secret")
    config = load_agent_file(_write(tmp_path, text))
    assert config.keys is not None
    assert config.keys.trusted == tmp_path / "keys"


@pytest.mark.parametrize(
    "text",
    ["", "[1, 2]\n", "btcap: 1\nrobot: [\n", "\tbad"],
)
def test_files_that_are_not_a_config_say_so(tmp_path: Path, text: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(AgentConfigError, match=str(path)):
        load_agent_file(path)


def test_an_unreadable_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(AgentConfigError, match=r"missing\.yaml: cannot read"):
        load_agent_file(tmp_path / "missing.yaml")


def test_capability_file_errors_name_the_config_field_and_the_capability_file(
    tmp_path: Path,
) -> None:
    impl = _write(tmp_path, "btcap_implementation: 1\nname: x\ninterface: Nope\ntree: t.yaml\n")
    path = _write(tmp_path, GOOD.replace(str(CAPS / "greet.yaml"), str(impl)), "cfg.yaml")
    config = load_agent_file(path)
    with pytest.raises(AgentConfigError) as err:
        config.load_capabilities(default_registry(plugins=False))
    message = str(err.value)
    assert message.startswith(f"{path}: capabilities.implementations[0]: {impl}: interface")
    # an operator loads only the interfaces
    interfaces, impls = config.load_capabilities(
        default_registry(plugins=False), implementations=False
    )
    assert (len(interfaces), impls) == (1, [])


def test_keys_make_an_encrypted_transport_and_bad_key_files_are_named(tmp_path: Path) -> None:
    zmq_auth = pytest.importorskip("zmq.auth")
    keys = tmp_path / "keys"
    keys.mkdir()
    for robot in ("alpha", "beta"):  # the seed's key too: only the team is dialled
        zmq_auth.create_certificates(str(keys), robot)
    text = GOOD + "keys: {secret: keys/alpha.key_secret, trusted: keys}\n"
    config = load_agent_file(_write(tmp_path, text))
    with pytest.raises(AgentConfigError) as info:  # keys made before roles: say how to fix
        config.transport(protocol_registry())
    assert str(info.value).count("\n") == 0
    assert "keys.trusted: " in str(info.value)
    assert "alpha.key: no role" in str(info.value)
    assert "btcap keys new alpha --role" in str(info.value)
    for robot in ("alpha", "beta"):
        for suffix in (".key", ".key_secret"):
            (keys / f"{robot}{suffix}").unlink()
        write_key_pair(keys, robot, "robot")
    transport = config.transport(protocol_registry())
    try:
        assert transport.curve is not None
    finally:
        transport.close()
    (keys / "alpha.key_secret").write_text("not a certificate")
    with pytest.raises(AgentConfigError, match=r"keys\.secret: "):
        load_agent_file(_write(tmp_path, text)).transport(protocol_registry())


def test_the_silent_connection_guards_reach_the_transport(tmp_path: Path) -> None:
    text = GOOD.replace(
        BIND, f"{BIND}\n  hello_timeout_s: 2.5\n  max_newcomers: 16\n  links_per_peer: 3"
    )
    config = load_agent_file(_write(tmp_path, text))
    assert (config.network.hello_timeout_s, config.network.links_per_peer) == (2.5, 3)
    transport = config.transport(protocol_registry())
    try:
        assert transport.newcomers == (2.5, 16, 3)
    finally:
        transport.close()
    transport = load_agent_file(_write(tmp_path, GOOD)).transport(protocol_registry())
    try:  # the transport's own defaults
        assert transport.newcomers == (10.0, 128, LINKS_PER_PEER)
    finally:
        transport.close()


def test_a_keyless_bind_other_hosts_reach_is_refused_naming_the_field(tmp_path: Path) -> None:
    text = GOOD.replace("tcp://127.0.0.1:*", "tcp://0.0.0.0:*\n  advertise: tcp://192.0.2.1:7")
    config = load_agent_file(_write(tmp_path, text))
    with pytest.raises(AgentConfigError) as info:
        config.transport(protocol_registry())
    message = str(info.value)  # in the file's and the CLI's words, not Python's
    assert "network.bind: 'tcp://0.0.0.0:" in message
    assert "keys:" in message
    assert "--insecure" in message
    assert "insecure=True" not in message


def test_key_mistakes_curve_would_refuse_name_the_field_in_the_files_words(
    tmp_path: Path,
) -> None:
    """An unencrypted seed endpoint, a name (--as) or a seed without a key in the trusted
    folder, the robot's own key different there: each names its field."""
    keys = tmp_path / "keys"
    keys.mkdir()
    for robot in ("alpha", "beta"):
        write_key_pair(keys, robot)
    text = GOOD + "keys: {secret: keys/alpha.key_secret, trusted: keys}\n"

    def refusal(text: str, **kwargs: str) -> str:
        config = load_agent_file(_write(tmp_path, text))
        with pytest.raises(AgentConfigError) as info:
            config.transport(protocol_registry(), **kwargs)
        return str(info.value)

    said = refusal(text.replace("tcp://127.0.0.2:7102", "inproc://beta"))
    assert "network.seeds[0].endpoint: 'inproc://beta': inproc:// is not encrypted" in said
    said = refusal(text, robot="gamma")
    assert "keys.trusted: " in said
    assert "has no gamma.key, so teammates would refuse robot 'gamma' (--as)" in said
    (keys / "beta.key").unlink()
    said = refusal(text)
    assert "network.seeds[0].robot: 'beta': " in said
    assert "(keys.trusted) has no beta.key: we could not check it" in said
    (tmp_path / "old").mkdir()
    public, _ = write_key_pair(tmp_path / "old", "alpha")
    public.replace(keys / "alpha.key")  # the folder holds a key alpha had before
    said = refusal(text)
    assert "keys.secret: " in said
    assert "alpha.key_secret is not the key of robot 'alpha'" in said
    assert "system" not in said  # the file's words (robot), not Python's (system id)


def test_a_plugin_adds_implementations_actors_and_messages(tmp_path: Path) -> None:
    text = GOOD + (
        "plugin:\n"
        "  factory: btcap.team.demo:implementations\n"
        "  args: {cost: 2.5}\n"
        "  messages: btcap.sim.running.hosts:registry\n"
    )
    config = load_agent_file(_write(tmp_path, text))
    plugged = config.load_plugin()
    assert [i.interface.name for i in plugged.implementations] == ["Echo"]
    assert all(t in plugged.messages for t in SIM_MESSAGES)
    assert config.load_plugin(factory=False).implementations == []  # an observer runs nothing
    assert load_agent_file(_write(tmp_path, GOOD)).load_plugin().implementations == []


@pytest.mark.parametrize(
    ("plugin", "field"),
    [
        ("{factory: no.such.module:thing}", "plugin.factory"),
        ("{factory: btcap.team.demo:implementations, args: {colour: red}}", "plugin.args"),
        (
            "{factory: btcap.team.demo:implementations, messages: btcap.team.demo:implementations}",
            "plugin.messages",
        ),
        ("{args: {}}", "plugin"),
    ],
)
def test_plugin_errors_name_the_field(tmp_path: Path, plugin: str, field: str) -> None:
    path = _write(tmp_path, GOOD + f"plugin: {plugin}\n")
    with pytest.raises(AgentConfigError, match=f"robot.yaml: {field}"):
        load_agent_file(path).load_plugin()
