"""Options of an operation, each defined once: its default, range or choices, unit and help.

An operation's options are a frozen dataclass whose fields are made with :func:`option` and
which derives from :class:`Options`. The field is the one place an option is written: the
library takes the dataclass, ``bioplan`` builds its flags from :func:`option_specs`
(``app.cli._common.add_options``), the API builds its request fields from them
(``app.api.schemas.option_field``) and a job payload is ``to_dict()`` read back with
``from_dict``. Adding an option is one field (and its test).

Values are checked on construction (``__post_init__``, so also by ``dataclasses.replace``):
a number out of its range, a value not among its choices or an unknown name is an
:class:`OptionsError` naming the option and what was expected, in one line.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import operator
import types
import typing
from collections.abc import Mapping, Sequence
from typing import Any, Self

from app.errors import BioPlanError

__all__ = [
    "OptionSpec",
    "Options",
    "OptionsError",
    "check_option",
    "check_value",
    "option",
    "option_specs",
]


class OptionsError(BioPlanError):
    """An option out of its range or choices, of the wrong type, or not an option at all."""


_MISSING: Any = dataclasses.MISSING


def option(
    default: Any = _MISSING,
    *,
    help: str,
    unit: str | None = None,
    ge: float | None = None,
    gt: float | None = None,
    le: float | None = None,
    lt: float | None = None,
    choices: Sequence[Any] | None = None,
    min_items: int | None = None,
    max_items: int | None = None,
    default_factory: Any = _MISSING,
    interface_default: Any = _MISSING,
    flag: str | None = None,
    negated: bool = False,
    metavar: str | None = None,
    none_means: str | None = None,
    cli_scale: float | None = None,
    cli_unit: str | None = None,
    cli: bool = True,
    api: bool = True,
) -> Any:
    """A dataclass field of an :class:`Options` class with everything the interfaces need.

    Args:
        default: the library's default (or ``default_factory``).
        help: one line for people, without the unit or range (they are added where shown).
        unit: the value's unit (``"s"``, ``"kg"``, ``"deg"``), or None for a pure number/name.
        ge, gt, le, lt: the inclusive/exclusive bounds of a number (of each item of a list).
        choices: the allowed values (of each item, for a list option).
        min_items, max_items: how many items a list option holds.
        interface_default: the CLI's and API's default when it differs from the library's
            (``methods``: the CLI and API plan every standard method, the library the quick
            pair); both live here, nowhere else.
        flag: the CLI flag when it is not ``--`` + the name with dashes (``--method``).
        negated: a boolean whose flag says the opposite (``--allow-reversal`` sets
            ``no_reversal`` to False).
        metavar: the CLI's placeholder for the value.
        none_means: what None (the default of a nullable option) stands for, in words
            (``"the template's"``).
        cli_scale, cli_unit: the CLI takes the value in another unit (``--timestep-ms``: x1000,
            ``ms``).
        cli, api: whether the option is offered by ``bioplan`` and by the API's request model
            (False: library only, e.g. the report grid).
    """
    meta: dict[str, Any] = {"help": help, "cli": cli, "api": api}
    for key, value in (
        ("unit", unit),
        ("ge", ge),
        ("gt", gt),
        ("le", le),
        ("lt", lt),
        ("min_items", min_items),
        ("max_items", max_items),
        ("flag", flag),
        ("metavar", metavar),
        ("none_means", none_means),
        ("cli_scale", cli_scale),
        ("cli_unit", cli_unit),
    ):
        if value is not None:
            meta[key] = value
    if choices is not None:
        meta["choices"] = tuple(choices)
    if negated:
        meta["negated"] = True
    if interface_default is not _MISSING:
        meta["interface_default"] = interface_default
    if default_factory is not _MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


@dataclasses.dataclass(frozen=True)
class OptionSpec:
    """One option as every interface reads it (from its field and metadata).

    Attributes:
        name: the field name (the API's and the job payload's key).
        kind: ``float``, ``int``, ``str``, ``bool`` or ``object`` (anything else) of the value
            (of each item for a list option).
        nullable: None is allowed (it means "the library decides", said in ``help``).
        sequence: the value is a list (a tuple in the dataclass).
        default: the library's default.
        interface_default: the CLI's and API's default (the library's unless stated).
        meta: the field's metadata (help, unit, bounds, choices, CLI details).
    """

    name: str
    kind: type
    nullable: bool
    sequence: bool
    default: Any
    interface_default: Any
    meta: Mapping[str, Any]

    @property
    def help(self) -> str:
        return str(self.meta["help"])

    @property
    def unit(self) -> str | None:
        return self.meta.get("unit")

    @property
    def choices(self) -> tuple[Any, ...] | None:
        return self.meta.get("choices")

    def bounds(self) -> dict[str, float]:
        """``{"ge": 2, "le": 1000}``: the bounds of a number (of each item of a list)."""
        return {k: self.meta[k] for k in ("ge", "gt", "le", "lt") if k in self.meta}

    def range_text(self) -> str:
        """The range in words: ``"> 0 and <= 600 s"`` ('' without bounds)."""
        signs = {"ge": ">=", "gt": ">", "le": "<=", "lt": "<"}
        parts = [f"{signs[k]} {v:.10g}" for k, v in self.bounds().items()]
        if not parts:
            return ""
        return " and ".join(parts) + (f" {self.unit}" if self.unit else "")

    def description(self) -> str:
        """The help with the unit and what None means: ``"motion time [s]"``."""
        text = self.help + (f" [{self.unit}]" if self.unit else "")
        return text + (
            f" (default: {self.meta['none_means']})" if "none_means" in self.meta else ""
        )


def _base_type(annotation: Any) -> tuple[type, bool, bool]:
    """(item type, nullable, sequence) of a field's resolved annotation."""
    args = typing.get_args(annotation)
    origin = typing.get_origin(annotation)
    nullable = False
    if origin in (typing.Union, types.UnionType):
        rest = [a for a in args if a is not type(None)]
        nullable = len(rest) < len(args)
        annotation = rest[0] if len(rest) == 1 else object
        args, origin = typing.get_args(annotation), typing.get_origin(annotation)
    if origin is typing.Literal:
        return type(args[0]), nullable, False
    if origin in (tuple, list) and args and (len(args) == 1 or args[-1] is Ellipsis):
        item, _, _ = _base_type(args[0])
        return item, nullable, True
    if annotation in (float, int, str, bool):
        return annotation, nullable, False
    return object, nullable, False


#: option_specs' answers by class (a class's fields never change).
_SPECS: dict[type, tuple[OptionSpec, ...]] = {}


def option_specs(cls: type) -> tuple[OptionSpec, ...]:
    """Every option of an options dataclass, in field order."""
    if cls not in _SPECS:
        _SPECS[cls] = _specs_of(cls)
    return _SPECS[cls]


def _specs_of(cls: type) -> tuple[OptionSpec, ...]:
    hints = typing.get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        kind, nullable, sequence = _base_type(hints[f.name])
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            default = None
        meta = dict(f.metadata)
        out.append(
            OptionSpec(
                name=f.name,
                kind=kind,
                nullable=nullable,
                sequence=sequence,
                default=default,
                interface_default=meta.get("interface_default", default),
                meta=meta,
            )
        )
    return tuple(out)


def check_option(name: str, value: Any, allowed: Sequence[Any], *, what: str = "") -> None:
    """Refuse ``value`` unless it is one of ``allowed``, naming the option and the choices."""
    if value not in allowed:
        shown = ", ".join(str(a) for a in allowed)
        raise OptionsError(f"unknown {what or name} {value!r} (expected one of: {shown})")


def _number(spec: OptionSpec, value: Any) -> Any:
    """``value`` as the spec's number type, within its bounds, else an OptionsError."""
    name = spec.name
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise OptionsError(f"{name} must be a number, got {value!r}")
    if spec.kind is int:
        if not (isinstance(value, numbers.Integral) or float(value).is_integer()):
            raise OptionsError(f"{name} must be a whole number, got {value!r}")
        value = int(value) if isinstance(value, numbers.Integral) else int(float(value))
    else:
        value = float(value)
        if not math.isfinite(value):
            raise OptionsError(f"{name} must be a finite number, got {value}")
    unit = f" {spec.unit}" if spec.unit else ""
    for key, sign, ok in (
        ("ge", ">=", operator.ge),
        ("gt", ">", operator.gt),
        ("le", "<=", operator.le),
        ("lt", "<", operator.lt),
    ):
        bound = spec.meta.get(key)
        if bound is not None and not ok(value, bound):
            raise OptionsError(f"{name} must be {sign} {bound:.10g}{unit}, got {value:.10g}")
    return value


def _item(spec: OptionSpec, value: Any) -> Any:
    if spec.choices is not None:
        check_option(spec.name, value, spec.choices)
        return value
    if spec.kind in (int, float):
        return _number(spec, value)
    if spec.kind is bool and not isinstance(value, bool):
        raise OptionsError(f"{spec.name} must be true or false, got {value!r}")
    if spec.kind is str and not isinstance(value, str):
        raise OptionsError(f"{spec.name} must be text, got {value!r}")
    return value


def check_value(spec: OptionSpec, value: Any) -> Any:
    """``value`` checked against ``spec`` and normalised (lists as tuples, "a,b" as ("a", "b")).

    Raises:
        OptionsError: naming the option and what was expected.
    """
    if value is None:
        if spec.nullable:
            return None
        raise OptionsError(f"{spec.name} must be given (it has no 'none')")
    if not spec.sequence:
        return _item(spec, value)
    if isinstance(value, str):
        value = [v.strip() for v in value.split(",") if v.strip()]
    if not isinstance(value, Sequence):
        raise OptionsError(f"{spec.name} must be a list, got {value!r}")
    items = tuple(_item(spec, v) for v in value)
    low, high = spec.meta.get("min_items"), spec.meta.get("max_items")
    if low is not None and len(items) < low:
        raise OptionsError(f"{spec.name} needs at least {low} item(s), got {len(items)}")
    if high is not None and len(items) > high:
        raise OptionsError(f"{spec.name} takes at most {high} item(s), got {len(items)}")
    return items


def _plain(value: Any) -> Any:
    """A value as JSON holds it: tuples as lists, sets as sorted lists, mappings as dicts."""
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, (set, frozenset)):
        return sorted(value)
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    return value


class Options:
    """Base of the options dataclasses: checked values, ``to_dict``/``from_dict``."""

    def __post_init__(self) -> None:
        for spec in option_specs(type(self)):
            object.__setattr__(self, spec.name, check_value(spec, getattr(self, spec.name)))

    def to_dict(self) -> dict[str, Any]:
        """Every option by name, lists as lists (JSON-ready: a job payload's options)."""
        out: dict[str, Any] = {}
        for spec in option_specs(type(self)):
            out[spec.name] = _plain(getattr(self, spec.name))
        return out

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(s.name for s in option_specs(cls))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, ignore_unknown: bool = False) -> Self:
        """The options in ``data``; absent ones keep their defaults.

        Args:
            data: option name -> value (a request's or job payload's fields).
            ignore_unknown: take only this class's options from ``data`` (a job payload holds
                the robot and task beside them); by default an unknown key is an error.

        Raises:
            OptionsError: an unknown key (named), or a value out of its range or choices.
        """
        known = set(cls.names())
        unknown = sorted(set(data) - known)
        if unknown and not ignore_unknown:
            raise OptionsError(
                f"unknown option(s) {', '.join(unknown)} of {cls.__name__} (expected some of: "
                f"{', '.join(cls.names())})"
            )
        return cls(**{k: v for k, v in data.items() if k in known})

    @classmethod
    def from_payload(cls, payload: Mapping[str, Any]) -> Self:
        """The options of a job payload or request body: this class's keys only (the robot,
        task and label stay the caller's), and a None where the option takes none means "the
        default" (payloads stored before the option had one)."""
        nullable = {s.name for s in option_specs(cls) if s.nullable}
        return cls.from_dict(
            {k: v for k, v in payload.items() if v is not None or k in nullable},
            ignore_unknown=True,
        )

    def replace(self, **changes: Any) -> Self:
        """A copy with ``changes`` (checked; an unknown name is an error naming it)."""
        unknown = sorted(set(changes) - set(self.names()))
        if unknown:
            raise OptionsError(
                f"unknown option(s) {', '.join(unknown)} of {type(self).__name__} (expected "
                f"some of: {', '.join(self.names())})"
            )
        return dataclasses.replace(self, **changes)  # type: ignore[type-var]
