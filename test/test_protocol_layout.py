"""The message layout is written only in msg_defs/msg/*.msg: the package, its docs and benches hold no
second copy of a message's fields (a hand-written codec, a field tuple, a table of field types), and
no module but the protocol's packs CDR by hand. No ROS processes."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from bev_mdo.protocol import messages

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "bev_mdo"
RUN = 3  # this many fields of one message in their .msg order make a copy of its layout
GENERIC = {"header"}  # a field every message has: not a sign of a copy on its own


def _layouts() -> dict[str, list[tuple[str, str]]]:
    """{message: [(type, field), ...]} in .msg order, from the .msg files themselves."""
    out = {}
    for name in messages.NAMES:
        fields = []
        for line in messages.msg_text(name).splitlines():
            line = line.split("#", 1)[0].strip()
            if line and "=" not in line:
                ftype, fname = line.split()[:2]
                fields.append((ftype, fname))
        out[name] = fields
    return out


LAYOUTS = _layouts()


def _runs(sequence: list[str], fields: list[str]) -> list[tuple[str, ...]]:
    """Runs of RUN consecutive items of ``sequence`` that are RUN consecutive fields of a message."""
    windows = {tuple(fields[k:k + RUN]) for k in range(len(fields) - RUN + 1)}
    windows = {w for w in windows if not set(w) <= GENERIC}
    return [tuple(sequence[k:k + RUN]) for k in range(len(sequence) - RUN + 1) if tuple(sequence[k:k + RUN]) in windows]


def _python_names(source: str) -> list[list[str]]:
    """The string elements of every tuple, list and set display of a Python source (how a field tuple
    or a class's ``__slots__`` spells a layout: ``("header", "run_id", "evaluation_id", ...)``).
    Reading or setting fields by name is not a layout, nor are the keys of a record dict; packing
    fields in order is, and test_no_module_but_the_protocol_packs_cdr finds that."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
            out.append([e.value for e in node.elts if isinstance(e, ast.Constant) and isinstance(e.value, str)])
    return out


def copies_in_python(source: str) -> list[tuple[str, tuple]]:
    """(message, fields) for every run of a message's fields written out in a Python source."""
    found = []
    for seq in _python_names(source):
        for msg, layout in LAYOUTS.items():
            found += [(msg, run) for run in _runs(seq, [f for _, f in layout])]
    return found


def copies_in_text(text: str) -> list[tuple[str, tuple]]:
    """(message, fields) for every run of "type field" pairs of a message written out in a text."""
    found = []
    for msg, layout in LAYOUTS.items():
        typed = [f"{t} {f}" for t, f in layout]
        seq = [" ".join(m) for m in re.findall(r"([\w/]+(?:\[\])?) (\w+)", text)]
        found += [(msg, run) for run in _runs(seq, typed)]
    return found


PACKERS = re.compile(r"struct\.(Struct|pack|unpack|pack_into|unpack_from|calcsize)\(|\.(to|from)_bytes\(")


def _python_files():
    return sorted(p for p in [*PACKAGE.rglob("*.py"), *(ROOT / "bench").rglob("*.py"), *(ROOT / "scripts").rglob("*.py")]
                  if "__pycache__" not in p.parts)


def test_the_detector_finds_a_hand_written_layout():
    """The check can fail: the shapes of the codec and the docs table it replaced are found."""
    slots = '__slots__ = ("header", "run_id", "evaluation_id", "sequence", "iteration", "attempt")'
    assert ("EvaluationRequest", ("header", "run_id", "evaluation_id")) in copies_in_python(slots)
    assert PACKERS.search('_U64X2 = struct.Struct("<QQ")') and PACKERS.search("n = int.from_bytes(data[at:at + 4])")
    table = "| `string[] names`, `uint32 batch_size`, `float64[] values` |"
    assert copies_in_text(table.replace("`", "")) == [("NamedArray", ("string[] names", "uint32 batch_size",
                                                                      "float64[] values"))]
    assert copies_in_python("def f(run_id, names):\n    return {'run_id': run_id}") == []


@pytest.mark.parametrize("path", _python_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_python_module_writes_a_message_layout(path):
    assert copies_in_python(path.read_text(encoding="utf-8")) == [], \
        f"{path.relative_to(ROOT)} spells out a message's fields; read them from bev_mdo.protocol (the .msg files)"


def test_no_doc_writes_a_message_layout():
    docs = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    found = {str(p.relative_to(ROOT)): copies_in_text(p.read_text(encoding="utf-8").replace("`", "")) for p in docs}
    assert {k: v for k, v in found.items() if v} == {}, "docs copy a message's fields; point to msg_defs/msg instead"


def test_no_module_but_the_protocol_packs_cdr():
    """CDR is packed and unpacked only by the generated code of bev_mdo/protocol (rosbags)."""
    hits = [str(p.relative_to(ROOT)) for p in _python_files()
            if PACKERS.search(p.read_text(encoding="utf-8")) and p.parent != PACKAGE / "protocol"]
    assert hits == []


def test_the_msg_files_ship_with_the_package():
    """The protocol reads its .msg files from the package when installed (setup.py copies them)."""
    setup = (ROOT / "setup.py").read_text(encoding="utf-8")
    assert "msg_defs" in setup and '"bev_mdo", "protocol", "msg"' in setup
    assert set(messages.NAMES) == {p.stem for p in (ROOT / "msg_defs" / "msg").glob("*.msg")}
