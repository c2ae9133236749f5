"""SIGINT or SIGTERM at any step of a command ends it as interrupted: the one line, exit status 130 (143).

A trial of `bev-mdo calibrate` found three ways it did not. A signal landing in a ctypes callback (numba's
compiler, through llvmlite) or an import lock's callback was swallowed ("Exception ignored on calling ctypes
callback"): the fit went on, wrote its set and exited 0. A signal inside compiled code surfaced as another
exception ("SystemError: CPUDispatcher(...) returned a result with an exception set"; "ImportError:
initialization failed" for a scipy module whose import it cut): exit 7, an internal error. And one during the
start-up imports (the subcommand's module, before its parser) was a Python traceback (exit -2, or 1 for
SIGTERM). Here the signal's handler is called at the step named, as the signal would call it.
"""
from __future__ import annotations

import ctypes
import signal

import pytest

from bev_mdo.cli import main

EXIT = {signal.SIGINT: 130, signal.SIGTERM: 143}
LINE = {signal.SIGINT: "bev-mdo: interrupted", signal.SIGTERM: "bev-mdo: terminated (SIGTERM)"}
SIGNALS = pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])


@pytest.fixture(autouse=True)
def sigint_at_its_default():
    """bev-mdo takes SIGINT only where it is not ignored (a shell's `&` job): here it is not."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def _signal(sig) -> None:
    """The signal, taken by bev-mdo's handler as the kernel's signal would be (it raises)."""
    signal.getsignal(sig)(sig, None)


def _swallowed(sig) -> None:
    """The signal, taken in a ctypes callback, which swallows what its handler raises (Python prints "Exception
    ignored on calling ctypes callback function"), as numba's compiler calls llvmlite's."""
    ctypes.CFUNCTYPE(None)(lambda: _signal(sig))()


def _main(argv) -> int:
    try:
        return main(argv)
    except BaseException as exc:  # noqa: BLE001 - (not raised on to pytest: a KeyboardInterrupt would stop it)
        pytest.fail(f"main raised {exc!r}")


@SIGNALS
def test_a_swallowed_signal_stops_calibrate_before_it_writes_its_set(tmp_path, monkeypatch, capsys, sig):
    from bev_mdo.models import calibrate

    usable = calibrate.usable

    def swallowing(*a, **k):  # the first prediction: numba compiles (its callbacks swallow a KeyboardInterrupt)
        _swallowed(sig)
        return usable(*a, **k)

    monkeypatch.setattr(calibrate, "usable", swallowing)
    written = tmp_path / "set.yaml"
    status = _main(["calibrate", "--write", str(written)])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == EXIT[sig] and err == [LINE[sig]], (status, err)
    assert not written.exists()


@SIGNALS
@pytest.mark.parametrize("argv, module, step, error", [
    (["calibrate"], "bev_mdo.models.calibrate", "usable",
     SystemError("CPUDispatcher(<function _battery>) returned a result with an exception set")),
    (["optimize", "config/leaf_nedc.yaml", "--transport", "inprocess", "--no-record"], "bev_mdo.mdo.driver",
     "run_optimization", ImportError("initialization failed"))])
def test_what_surfaces_after_a_signal_is_the_signal_not_an_error(monkeypatch, capsys, sig, argv, module, step, error):
    def cut(*a, **k):  # the signal, and what the code it landed in raised instead of it
        _swallowed(sig)
        raise error

    monkeypatch.setattr(f"{module}.{step}", cut)
    from bev_mdo.testing import REPO

    monkeypatch.chdir(REPO)
    status = _main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert status == EXIT[sig] and err == [LINE[sig]], (status, err)


@SIGNALS
@pytest.mark.parametrize("swallowed", [False, True], ids=["raised", "cut-the-import"])
def test_a_signal_during_the_start_up_imports_is_one_line(monkeypatch, capsys, sig, swallowed):
    import importlib

    real = importlib.import_module

    def importing(name, *a, **k):  # the subcommand's module (numpy, scipy, ...: 0.1-0.6 s of a command's start)
        if name.startswith("bev_mdo.cli."):
            if not swallowed:
                _signal(sig)
            _swallowed(sig)
            raise ImportError("initialization failed")
        return real(name, *a, **k)

    monkeypatch.setattr(importlib, "import_module", importing)
    status = _main(["validate"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == EXIT[sig] and err == [LINE[sig]], (status, err)


def test_a_command_whose_end_is_a_signal_keeps_its_status(monkeypatch, capsys):
    """`record` and `node` end on Ctrl-C (exit 0, as `ros2 bag record`): the signal is not raised again."""
    from bev_mdo.ros import recorder_node

    def recording(argv):
        _swallowed(signal.SIGINT)  # (the recorder's own deferred block keeps it; it then closes its bag)
        return 0

    monkeypatch.setattr(recorder_node, "main", recording)
    monkeypatch.setattr("bev_mdo.cli.flags.join_domain", lambda args: None)
    assert _main(["record"]) == 0


def test_a_signal_a_callback_swallowed_prints_no_traceback(monkeypatch):
    """Python printed "Exception ignored on calling ctypes callback function ... KeyboardInterrupt" with a traceback
    (sys.unraisablehook) before the command's own line, and after it what objects the signal left half-made said
    as they were collected (llvmlite: "Exception ignored in: <function ObjectRef.__del__ ...> AttributeError").
    Once a signal fired it ends the command with its one line; before, such an error is printed as ever."""
    import sys

    from bev_mdo import interrupts

    seen = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: seen.append(type(u.exc_value).__name__))
    previous = interrupts.install()
    try:
        ctypes.CFUNCTYPE(None)(lambda: 1 / 0)()  # not a signal: as before
        _swallowed(signal.SIGINT)
        assert interrupts.pending() is KeyboardInterrupt
        ctypes.CFUNCTYPE(None)(lambda: 1 / 0)()  # (a finaliser of something the signal cut short)
    finally:
        interrupts.restore(previous)
    assert seen == ["ZeroDivisionError"]
