"""Reading a TOML configuration file into a validated :class:`~cnctwin.config.MachiningConfig`."""

from __future__ import annotations

import os
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, TypeVar, overload

from pydantic import BaseModel, ValidationError
from pydantic_core import ErrorDetails

from cnctwin.config.machining import MachiningConfig
from cnctwin.errors import ConfigError

__all__ = ["describe_validation_error", "load_config"]

_SCALARS = (str, int, float, bool)

#: Pydantic's error types of a numeric bound; their message gives the key's whole valid range.
_BOUND_ERRORS = ("greater_than", "greater_than_equal", "less_than", "less_than_equal")
_BOUND_SYMBOLS = (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<="))

_Model = TypeVar("_Model", bound=MachiningConfig)


@overload
def load_config(path: str | os.PathLike[str]) -> MachiningConfig: ...


@overload
def load_config(path: str | os.PathLike[str], *, model: type[_Model]) -> _Model: ...


def load_config(
    path: str | os.PathLike[str], *, model: type[MachiningConfig] = MachiningConfig
) -> MachiningConfig:
    """Read and validate a configuration file.

    Parameters
    ----------
    path
        A TOML file; relative paths inside it (``tool_table``) are relative to its folder.
        A CAMotics project (``.camotics``) is read for its tools and workpiece instead
        (:func:`cnctwin.config.camotics.load_camotics_project`; only with the default
        ``model``).
    model
        The root model to validate against: :class:`MachiningConfig` or a subclass that adds
        tables (e.g. :class:`cnctwin.twin.config.RunConfig`, the running twin's file).

    Returns
    -------
    MachiningConfig
        The validated configuration, an instance of ``model``.

    Raises
    ------
    cnctwin.errors.ConfigError
        If the file cannot be read, is not valid TOML, or a value is invalid; the message is
        one line ``"FILE: key.path: what is wrong; got VALUE"``.
    """
    path = Path(path)
    source = str(path)
    if path.suffix.lower() == ".camotics" and model is MachiningConfig:
        from cnctwin.config.camotics import load_camotics_project

        return load_camotics_project(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as err:
        raise ConfigError(f"cannot read configuration: {err.strerror}", source) from err
    except UnicodeDecodeError as err:
        raise ConfigError(f"not UTF-8 text (byte {err.start}): {err.reason}", source) from err
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"invalid TOML: {err}", source) from err
    try:
        return model.model_validate(data, context={"base_dir": path.parent})
    except ValidationError as err:
        raise ConfigError(describe_validation_error(err, model), source) from err


def describe_validation_error(error: ValidationError, root: type[BaseModel]) -> str:
    """One line for a pydantic error: key path, what is wrong, what is valid, the value.

    Parameters
    ----------
    error
        The validation error of ``root``.
    root
        The model that was validated, used to list the valid keys next to an unknown one.

    Returns
    -------
    str
        E.g. ``"machine.axes.x.max_mm: must be greater than min_mm (-10.0); got -20.0"``,
        followed by ``" (and N more problems)"`` when there are several.
    """
    details = error.errors(include_url=False)
    first = details[0]
    text = f"{_key_path(first['loc'], root)}: {_problem(first, root)}"
    if len(details) > 1:
        text += f" (and {len(details) - 1} more problem{'s' if len(details) > 2 else ''})"
    return text


def _key_path(loc: tuple[int | str, ...], root: type[BaseModel]) -> str:
    """The TOML key path of an error's location, without pydantic's names of the members of
    a union (``lobes.steps``, not ``lobes.steps.constrained-int``)."""
    path = ""
    annotation: Any = root
    for part in loc:
        if _is_union(annotation) and isinstance(part, str) and _is_member_tag(part):
            continue
        annotation = _model_or_item(annotation, part) if annotation is not None else None
        if isinstance(part, int):
            path += f"[{part}]"
        else:
            path += f".{part}" if path else str(part)
    return path or "(top level)"


def _is_union(annotation: Any) -> bool:
    return typing.get_origin(annotation) in (typing.Union, types.UnionType)


def _is_member_tag(part: str) -> bool:
    """Whether ``part`` is pydantic's name of a union member (``int``, ``constrained-float``,
    ``literal['auto']``) rather than a key."""
    return part in ("int", "float", "str", "bool") or part.startswith(("constrained-", "literal["))


def _problem(detail: ErrorDetails, root: type[BaseModel]) -> str:
    kind = detail["type"]
    if kind == "extra_forbidden":
        keys = _valid_keys(root, detail["loc"][:-1])
        return "unknown key" + (f"; valid keys: {', '.join(keys)}" if keys else "")
    if kind == "missing":
        return (
            "required key is missing" if isinstance(detail["loc"][-1], str) else "item is missing"
        )
    message = detail["msg"].removeprefix("Value error, ")
    bounds = _range_text(root, detail["loc"]) if kind in _BOUND_ERRORS else ""
    if bounds:
        message = f"must be {bounds}"
    elif message.startswith("Input should be"):
        message = "must be" + message.removeprefix("Input should be")
    else:
        message = message[:1].lower() + message[1:]
    value = detail.get("input")
    if isinstance(value, _SCALARS):
        message += f"; got {value!r}"
    return message


def _range_text(root: type[BaseModel], loc: tuple[int | str, ...]) -> str:
    """The declared range of the number at ``loc`` below ``root``: ``"> 0 and <= 1000"``;
    empty if it cannot be told."""
    annotation: Any = root
    for part in loc[:-1]:
        annotation = _model_or_item(annotation, part)
        if annotation is None:
            return ""
    metadata: list[Any] = []
    last = loc[-1] if loc else None
    model = _model_or_item(annotation, None)
    if isinstance(last, str) and model is not None:
        for name, field in model.model_fields.items():
            if last in (name, field.alias):
                metadata = list(field.metadata)
    else:
        item = _model_or_item(annotation, last)
        if typing.get_origin(item) is typing.Annotated:
            for extra in typing.get_args(item)[1:]:
                metadata += getattr(extra, "metadata", [extra])
    parts = [
        f"{symbol} {_number(getattr(bound, attr))}"
        for attr, symbol in _BOUND_SYMBOLS
        for bound in metadata
        if isinstance(getattr(bound, attr, None), int | float)
    ]
    return " and ".join(parts)


def _number(value: float) -> str:
    """A bound as written in the documentation: ``1000000``, ``0.01``, ``1e+12``."""
    if float(value).is_integer() and abs(value) < 1e7:
        return str(int(value))
    return f"{value:g}"


def _valid_keys(root: type[BaseModel], loc: tuple[int | str, ...]) -> list[str]:
    """The keys allowed in the table at ``loc`` below ``root``; empty if it cannot be told."""
    annotation: Any = root
    for part in loc:
        annotation = _model_or_item(annotation, part)
        if annotation is None:
            return []
    model = _model_or_item(annotation, None)
    if model is None:
        return []
    return [field.alias or name for name, field in model.model_fields.items()]


def _model_or_item(annotation: Any, part: int | str | None) -> Any:
    """Step from a type to the type of its key ``part`` (``None``: the model itself)."""
    origin = typing.get_origin(annotation)
    if origin in (typing.Union, types.UnionType):
        members = [a for a in typing.get_args(annotation) if a is not type(None)]
        return _model_or_item(members[0], part) if len(members) == 1 else None
    if isinstance(part, int) and origin is tuple:
        items = typing.get_args(annotation)
        if not items:
            return None
        return items[0] if items[-1] is Ellipsis else items[min(part, len(items) - 1)]
    if isinstance(part, int) and origin is list:
        return typing.get_args(annotation)[0]
    if isinstance(part, str) and origin is dict:
        return typing.get_args(annotation)[1]
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        if part is None:
            return annotation
        for name, field in annotation.model_fields.items():
            if part in (name, field.alias):
                return field.annotation
    return None
