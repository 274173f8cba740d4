"""An argparse CLI generated from a dataclass: one flag per field, its comment as help.

The dataclass stays the single copy of every default (STYLE: config is typed
dataclasses, the CLI is generated from them).
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import re
import typing


def field_comments(cls) -> dict[str, str]:
    """`name: type = default  # comment` lines of a dataclass body -> {name: comment}."""
    source = inspect.getsource(cls)
    return dict(re.findall(r"^\s+(\w+):[^#\n]*#\s*(.+)$", source, flags=re.MULTILINE))


def build_parser(cls, description: str) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=description, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    comments = field_comments(cls)
    hints = typing.get_type_hints(cls)
    for field in dataclasses.fields(cls):
        flag = "--" + field.name.replace("_", "-")
        kind = hints[field.name]
        help_text = comments.get(field.name, "")
        if kind is bool:
            parser.add_argument(flag, action=argparse.BooleanOptionalAction, default=field.default, help=help_text)
            continue
        origin = typing.get_origin(kind)
        arguments = typing.get_args(kind)
        if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
            kind = next(argument for argument in arguments if argument is not type(None))
            origin, arguments = typing.get_origin(kind), typing.get_args(kind)
        if origin is tuple:
            parser.add_argument(flag, type=arguments[0], nargs="+", default=field.default, help=help_text)
        else:
            parser.add_argument(flag, type=kind, default=field.default, help=help_text)
    return parser


def parse_into(cls, description: str, argv: list[str] | None = None):
    """Parse argv into an instance of the dataclass `cls`."""
    namespace = build_parser(cls, description).parse_args(argv)
    values = vars(namespace)
    for field in dataclasses.fields(cls):
        if isinstance(values[field.name], list):
            values[field.name] = tuple(values[field.name])
    return cls(**values)
