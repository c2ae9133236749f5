"""A discipline class named in a config: found (``load_class``: ``module:Class`` on the config's
search_path) and given its options (``read_options``: declared once, a key not declared or a value of the
wrong type refused in one line when the config is loaded)."""
from __future__ import annotations

import dataclasses
import importlib
import inspect
import sys
import types
import typing
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from bev_mdo.mdo.discipline import Discipline
from bev_mdo.models.common import check_keys, is_number, text_hint


def _builds_from_options(cls: type) -> bool:
    """True when ``cls`` is built by passing its options to the constructor (no from_config of its own)."""
    own = getattr(cls, "from_config", None)
    return own is None or getattr(own, "__func__", None) is Discipline.from_config.__func__


def read_options(cls: type, options: Mapping[str, Any] | None, where: str) -> Any:
    """The options of a config entry for discipline class ``cls``, refused (one-line ValueError naming
    ``where.<key>`` and the nearest declared key) when a key is not declared:

    * ``cls.Options``, a dataclass: its fields are the keys, and a value must match its field's
      annotation when that is ``float``, ``int``, ``bool`` or ``str`` (:func:`_check_option_types`);
      returns an instance (defaults filled);
    * no ``from_config`` of its own: the constructor's keyword parameters (any with ``**kwargs``), a
      value checked the same way against the parameter's annotation, or, without one, not text or a bool
      where its default is a number (``loss=0.02`` given '2 %' failed every point, the option unnamed);
      returns the options as a dict;
    * else the class declares no option, and none may be given.

    A number that is not finite (``.nan``, ``.inf``), at any depth, is refused the same way: every point
    would fail at run time."""
    options = dict(options or {})
    _refuse_non_finite(where, options)
    spec = getattr(cls, "Options", None)
    if spec is not None and dataclasses.is_dataclass(spec):
        check_keys(where, options, [f.name for f in dataclasses.fields(spec) if f.init])
        _check_option_types(_type_hints(spec), options, where)
        return spec(**options)
    if _builds_from_options(cls):
        try:
            params = inspect.signature(cls).parameters
        except (TypeError, ValueError):
            return options
        if not any(p.kind is p.VAR_KEYWORD for p in params.values()):
            check_keys(where, options, [k for k, p in params.items() if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)])
        hints = _type_hints(cls.__init__)
        numeric = {k: _NumberDefault for k, p in params.items() if is_number(p.default) and p.annotation is p.empty}
        _check_option_types({**numeric, **hints}, options, where)
        return options
    check_keys(where, options, ())
    return options


class _NumberDefault:
    """The 'annotation' of a constructor parameter without one whose default is a number: text or a bool
    there is refused (anything else, None or a list, may be what the class takes too)."""


_OPTION_TYPES = {  # annotation -> (accepts the value, what it must be); any other annotation is not checked
    _NumberDefault: (lambda v: not isinstance(v, (str, bool, np.bool_)), "a number, as its default is"),
    float: (is_number, "a number (float)"),
    int: (lambda v: isinstance(v, (int, np.integer)) and not isinstance(v, bool), "a whole number (int)"),
    bool: (lambda v: isinstance(v, (bool, np.bool_)), "true or false (bool)"),
    str: (lambda v: isinstance(v, str), "text (str)"),
}


def _type_hints(obj: Any) -> dict:
    """The resolved annotations of a class or function (strings too: ``from __future__ import annotations``);
    {} when one does not resolve (a name imported only for type checking)."""
    try:
        return typing.get_type_hints(obj)
    except Exception:
        return {}


def _check_option_types(hints: Mapping[str, Any], options: Mapping[str, Any], where: str) -> None:
    """ValueError naming ``where.<key>`` for the first option whose value does not match its annotation in
    ``hints`` (``_OPTION_TYPES``: a float takes an int, not a bool or text); ``X | None`` takes None or what
    X takes; any other annotation is left alone."""
    for key, value in options.items():
        hint, args = hints.get(key), typing.get_args(hints.get(key))
        if len(args) == 2 and type(None) in args and typing.get_origin(hint) in (typing.Union, types.UnionType):
            hint = None if value is None else next(a for a in args if a is not type(None))
        accepts, what = _OPTION_TYPES.get(hint, (None, ""))
        if accepts is not None and not accepts(value):
            raise ValueError(f"{where}.{key}: {value!r} must be {what}{text_hint(value)}")


def _refuse_non_finite(where: str, value: Any) -> None:
    """ValueError naming the key path of the first non-finite number in ``value`` (mappings and lists)."""
    if isinstance(value, Mapping):
        for k, v in value.items():
            _refuse_non_finite(f"{where}.{k}", v)
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            _refuse_non_finite(f"{where}[{i}]", v)
    elif isinstance(value, (float, np.floating)) and not np.isfinite(value):
        raise ValueError(f"{where}: {float(value)!r} must be a finite number")


_OURS: set[str] = set()  # the top-level modules load_class imported (not loaded before it looked for them)


def load_class(spec: str, search_path: Sequence[str] = ()) -> type:
    """Import ``module:Class`` (or ``module.Class``) and return the class.

    The module is looked for first in the folders of ``search_path`` (the run config's: its own
    entries, the config file's folder, the working directory; config.py), in that order, then on
    Python's own path. A folder is put at the front of ``sys.path`` only when it holds the module's
    top-level package or file, so the same config resolves the same class in every process (the CLI
    in process, and each discipline node over ROS), whatever their PYTHONPATH. A module of that name
    that load_class imported before from another folder (another project's config in the same session) is
    loaded again from this one: a config never gets another project's class. A module loaded otherwise (bev_mdo,
    a package the caller imported) is never dropped.
    """
    if ":" in spec:
        mod_name, _, cls_name = spec.partition(":")
    else:
        mod_name, _, cls_name = spec.rpartition(".")
    if not mod_name or not cls_name:
        raise ValueError(f"discipline class {spec!r} must be written 'module:Class'")
    top = mod_name.split(".")[0]
    for folder in search_path:
        base = Path(folder)
        if (base / f"{top}.py").is_file() or (base / top).is_dir():
            loaded = sys.modules.get(top)
            if top in _OURS and loaded is not None and not _loaded_from(loaded, base / top):  # another config's
                for name in [m for m in sys.modules if m == top or m.startswith(top + ".")]:
                    del sys.modules[name]
                importlib.invalidate_caches()
                if str(base) in sys.path:
                    sys.path.remove(str(base))
            if str(base) not in sys.path:
                sys.path.insert(0, str(base))
            break
    fresh = top not in sys.modules  # (bev_mdo, or a package the caller imported: never dropped above)
    try:
        module = importlib.import_module(mod_name)
    except ImportError as exc:
        gone = [str(f) for f in search_path if not Path(f).is_dir()]  # a typo in search_path, most likely
        where = (f" (looked in {', '.join(map(str, search_path))} and the Python path"
                 + (f"; search_path folder {gone[0]} does not exist" if gone else "") + ")") if search_path else ""
        raise ValueError(f"cannot import module {mod_name!r} for class {spec!r}{where}: {exc}") from None
    except Exception as exc:  # the user's module raised while importing
        raise ValueError(f"module {mod_name!r} for class {spec!r} fails on import: "
                         f"{type(exc).__name__}: {exc}") from None
    if fresh:
        _OURS.add(top)
    try:
        return getattr(module, cls_name)
    except AttributeError:
        raise ValueError(f"module {mod_name!r} has no class {cls_name!r}") from None


def _loaded_from(module, place: Path) -> bool:
    """Whether a top-level ``module`` was loaded from ``place`` (its package folder) or ``place``.py."""
    files = [getattr(module, "__file__", None), *getattr(module, "__path__", [])]
    here, package = place.with_suffix(".py").resolve(), place.resolve()
    return any(f and (Path(f).resolve() == here or package in Path(f).resolve().parents or
                      Path(f).resolve() == package) for f in files)
