"""What a received message may cost to decode, checked on its raw MessagePack bytes
before it is decoded (sans-IO: bytes in, a reason or None out).

Decoding costs about one object per container, and a container costs one byte: a 3.5 MB
frame of small nested lists is millions of objects and about a second of CPU (most of
it the garbage collector's), while the same bytes as a string or a list of numbers
decode in milliseconds. So every message is held to at most :data:`MAX_CONTAINERS`
arrays and maps, nested at most :data:`MAX_DEPTH` deep, whatever its fields are (the
free-form ones, ``inputs``, ``outputs`` and the like, hold any value a peer likes).

The check is cheap for what peers really send. Every container starts with one of 48
byte values, so how many of those bytes a message holds bounds its containers and its
depth from above, counted in C (``bytes.translate``); only a message where that bound
passes :data:`MAX_DEPTH` is walked token by token, and the walk gives up after
:data:`MAX_SCANNED` values (numbers packed with such bytes, text in UTF-8).
"""

from __future__ import annotations

import msgspec

__all__ = [
    "MAX_CONTAINERS",
    "MAX_DEPTH",
    "MAX_SCANNED",
    "check_nesting",
    "message_tag",
    "split_envelope",
]

MAX_CONTAINERS = 32_768
"""Arrays and maps one message may hold (a path of 30,000 waypoints fits; at most a few
milliseconds of decoding)."""
MAX_DEPTH = 64
"""How deep they may nest, the message's own array counted."""
MAX_SCANNED = 131_072
"""Steps a walk takes before it gives up (about 20 ms of Python): a message whose bound
says it may nest too much must show it does not within this many. A run of numbers of
one kind (or of one-byte values) in an array is one step, skipped by a regular
expression; each other value is a step."""
_RUN_MIN = 4
"""Values left in an array from which a run of like ones is skipped in one step."""

_OPENERS = bytes([*range(0x80, 0xA0), 0xDC, 0xDD, 0xDE, 0xDF])
"""First bytes of fixmap, fixarray, array 16/32 and map 16/32."""
_NOTHING = bytes(range(256))

# How a first byte is read: a fixed size (>0), or 0 for the ones handled apart.
_SIZE = [0] * 256
for _b in [*range(0x00, 0x80), *range(0xE0, 0x100), 0xC0, 0xC2, 0xC3]:
    _SIZE[_b] = 1
for _b in range(0xA0, 0xC0):  # fixstr
    _SIZE[_b] = 1 + (_b & 0x1F)
for _b, _n in {
    0xCA: 5, 0xCB: 9, 0xCC: 2, 0xCD: 3, 0xCE: 5, 0xCF: 9, 0xD0: 2, 0xD1: 3, 0xD2: 5, 0xD3: 9,
    0xD4: 3, 0xD5: 4, 0xD6: 6, 0xD7: 10, 0xD8: 18,
}.items():  # fmt: skip
    _SIZE[_b] = _n
# Lengths that follow the first byte: (bytes of length, extra bytes before the data).
_ONE_BYTE = bytes(b for b, n in enumerate(_SIZE) if n == 1)
_RUNS = {b: _ONE_BYTE if n == 1 else bytes([b]) for b, n in enumerate(_SIZE) if n}
"""First bytes whose like ones are skipped in runs, and the first bytes counted alike."""
_SIZED = {0xC4: (1, 0), 0xC5: (2, 0), 0xC6: (4, 0), 0xD9: (1, 0), 0xDA: (2, 0), 0xDB: (4, 0)}
_SIZED |= {0xC7: (1, 1), 0xC8: (2, 1), 0xC9: (4, 1)}  # ext: a type byte, then the data
# Containers: (bytes of length, items per entry).
_LONG = {0xDC: (2, 1), 0xDD: (4, 1), 0xDE: (2, 2), 0xDF: (4, 2)}


def check_nesting(data: bytes | memoryview | msgspec.Raw) -> str | None:
    """Why the MessagePack value ``data`` nests too much (containers, depth), or None.

    Malformed or truncated data is left to the decoder (None): this only bounds cost."""
    if len(data) <= MAX_DEPTH:
        return None  # a container takes a byte: neither bound can be passed
    raw = data if type(data) is bytes else bytes(data)
    if len(raw) - len(raw.translate(_NOTHING, _OPENERS)) <= MAX_DEPTH:
        return None
    return _walk(raw)


def _walk(raw: bytes) -> str | None:
    size, sized, long, runs = _SIZE, _SIZED, _LONG, _RUNS
    end = len(raw)
    pos = containers = scanned = 0
    left = 1  # values still to read in the innermost open container
    stack: list[int] = []
    while pos < end:
        while not left:
            if not stack:
                return None
            left = stack.pop()
        left -= 1
        scanned += 1
        if scanned > MAX_SCANNED:
            return f"more than {MAX_SCANNED} steps to check it"
        b = raw[pos]
        n = size[b]
        if n:
            if left >= _RUN_MIN and b in runs:  # this one and like ones after it
                got = _run(raw, pos, n, left + 1, runs[b])
                left -= got - 1
                pos += got * n
            else:
                pos += n
            continue
        if 0x80 <= b <= 0x9F:  # fixmap, fixarray
            items = (b & 0x0F) * (2 if b < 0x90 else 1)
            pos += 1
        elif b in long:
            width, per = long[b]
            items = int.from_bytes(raw[pos + 1 : pos + 1 + width], "big") * per
            pos += 1 + width
        elif b in sized:
            width, extra = sized[b]
            pos += 1 + width + extra + int.from_bytes(raw[pos + 1 : pos + 1 + width], "big")
            continue
        else:
            return None  # 0xC1: not MessagePack; the decoder says so
        containers += 1
        if containers > MAX_CONTAINERS:
            return f"more than {MAX_CONTAINERS} arrays and maps"
        stack.append(left)
        if len(stack) > MAX_DEPTH:
            return f"nested more than {MAX_DEPTH} deep"
        left = items
    return None


def _run(raw: bytes, pos: int, n: int, most: int, firsts: bytes) -> int:
    """How many values of ``n`` bytes, each starting with one of ``firsts``, follow from
    ``pos`` (at most ``most``): every n-th byte compared in C, in windows that double."""
    got, window = 0, 16
    while got < most:
        window = min(window, most - got)
        starts = raw[pos + got * n : pos + (got + window) * n : n]
        like = len(starts) - len(starts.lstrip(firsts))
        got += like
        if like < window:
            break
        window *= 2
    return got


def message_tag(raw: bytes | memoryview | msgspec.Raw) -> bytes | None:
    """The tag of an encoded message (an array whose first item is its tag string), read
    without decoding it; None if it is not one (nil, or malformed: the decoder says)."""
    data = memoryview(raw)
    if len(data) < 2:
        return None
    b = data[0]
    if 0x90 <= b <= 0x9F:
        pos = 1
    elif b == 0xDC:
        pos = 3
    elif b == 0xDD:
        pos = 5
    else:
        return None
    t = data[pos] if pos < len(data) else 0
    if 0xA0 <= t <= 0xBF:
        start, n = pos + 1, t & 0x1F
    elif t == 0xD9 and pos + 1 < len(data):
        start, n = pos + 2, data[pos + 1]
    else:
        return None
    return bytes(data[start : start + n])


def split_envelope(data: memoryview) -> tuple[int, str, str, int] | None:
    """An encoded envelope's kind, sender's and recipient's systems, and where its message
    starts, read in Python: for a big frame, whose message msgspec would walk to reach
    the fields after it. None if it is not in the form btcap sends (the decoder says)."""
    if len(data) < 8 or data[0] != 0x95 or data[1] > 3:
        return None
    kind, pos = data[1], 2
    systems = []
    for _ in range(2):  # sender, recipient: [system, path]
        if data[pos] != 0x92:
            return None
        pos += 1
        for part in range(2):
            got = _str(data, pos)
            if got is None:
                return None
            start, pos = got
            if part == 0:
                try:
                    systems.append(bytes(data[start:pos]).decode())
                except UnicodeDecodeError:
                    return None
    return kind, systems[0], systems[1], pos


def _str(data: memoryview, pos: int) -> tuple[int, int] | None:
    """Where a string at ``pos`` starts and ends, if it is one."""
    if pos + 3 > len(data):
        return None
    b = data[pos]
    if 0xA0 <= b <= 0xBF:
        start, n = pos + 1, b & 0x1F
    elif b == 0xD9:
        start, n = pos + 2, data[pos + 1]
    elif b == 0xDA:
        start, n = pos + 3, int.from_bytes(data[pos + 1 : pos + 3], "big")
    else:
        return None
    return (start, start + n) if start + n <= len(data) else None
