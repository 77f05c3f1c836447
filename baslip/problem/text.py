"""Reading untrusted text: YAML with bounded size, and short excerpts for error messages.

A problem file is small. Anything that would make it large (a huge file, aliases that
expand to millions of values, nesting hundreds of levels deep, an alias that contains
itself) is refused before any value is built, so a hostile file costs neither memory nor
a many-megabyte error line.

Beyond YAML's safe loader:

* a key repeated in one mapping is an error, not "last one wins"; merge keys (``<<``)
  still work, and a mapping's own keys override merged ones as YAML intends;
* a key that is itself a list or a mapping (``{[z, ydot]: 0.4}``) is kept as a
  :class:`NonScalarKey`, so the schema can name the place and refuse it in one line;
* a number tag on text that is no such number (``!!float 'abc'``, ``!!int '0x'``) is
  kept as a :class:`MalformedNumber`, which the schema refuses naming its key.
"""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path
from typing import Any

import yaml
from yaml.nodes import MappingNode, ScalarNode, SequenceNode

from baslip.errors import ArgumentError, InputError, ProblemError

#: Largest problem file read, in bytes (the shipped ones are 1 to 2 kB).
MAX_BYTES = 64_000
#: Most values (scalars, lists and mappings) a file may hold once aliases are expanded.
MAX_VALUES = 20_000
#: Deepest nesting of lists and mappings.
MAX_DEPTH = 32
#: Longest excerpt of a value quoted in an error message, in characters.
EXCERPT = 40

_MERGE = "tag:yaml.org,2002:merge"


class UnreadableText(InputError):
    """Text that cannot be read as a problem file; the message is one short line."""


#: Most bits of an integer in a problem: more than a float can hold is no physical value.
MAX_INTEGER_BITS = 1024


#: Levels of nesting a message's key names.
_KEY_LEVELS = 4


class UnreadableData(ProblemError):
    """Plain data (a problem given from Python) that no problem file could hold."""


def check_plain_data(data: Any) -> None:
    """Refuse plain data that no problem file could hold, before any value is read: lists
    and mappings nested deeper than :data:`MAX_DEPTH` (a list that contains itself among
    them), more than :data:`MAX_VALUES` values, or an integer beyond a float's range
    (whose digits Python would refuse to print). Objects other than lists, tuples and
    mappings are left to the schema.

    Raises
    ------
    UnreadableData
        Naming the dotted key of the first offending entry.
    """
    count = [0]

    def walk(value: Any, key: str, depth: int) -> None:
        count[0] += 1
        if count[0] > MAX_VALUES:
            raise UnreadableData(key, f"the problem holds more than {MAX_VALUES} values")
        if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > MAX_INTEGER_BITS:
            raise UnreadableData(key, f"too large: an integer of more than {MAX_INTEGER_BITS} bits is beyond a float's range")
        if not isinstance(value, (list, tuple, dict)):
            return
        if depth >= MAX_DEPTH:
            raise UnreadableData(key, f"nested more than {MAX_DEPTH} levels deep (or a list that contains itself)")
        items = value.items() if isinstance(value, dict) else enumerate(value)
        for name, item in items:
            # The key names the entry's first levels (as deep as a problem file's keys go):
            # a key of every level of a deep nest would be long.
            walk(item, key if depth >= _KEY_LEVELS else f"{key}.{clip(str(name))}" if key else clip(str(name)),
                 depth + 1)

    walk(data, "", 0)


def path_argument(value: Any, name: str) -> str:
    """``value`` as a path string if it is a str or os.PathLike with no NUL in it;
    otherwise an :class:`~baslip.errors.ArgumentError` naming the argument ``name``."""
    try:
        text = os.fspath(value)
    except TypeError:
        raise ArgumentError(name, f"expected a path, got {type(value).__name__}") from None
    if isinstance(text, bytes):
        raise ArgumentError(name, "expected a path as text, got bytes")
    if "\0" in text:
        raise ArgumentError(name, f"a path cannot hold a NUL character: {excerpt(text)}")
    if not text:
        raise ArgumentError(name, "expected a path, got an empty string")
    return text


#: What a path that is not a regular file is, by its stat type.
_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISSOCK, "a socket"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"))


def file_kind(mode: int) -> str | None:
    """What a file of ``st_mode`` ``mode`` is when it is not a regular file
    (``"a FIFO"``, ``"a character device"``, ...); None for a regular file."""
    if stat.S_ISREG(mode):
        return None
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def small_file_text(path: Path) -> str:
    """The UTF-8 text of the regular file ``path``, of at most :data:`MAX_BYTES` bytes.

    It is opened without blocking and checked before anything is read, so a FIFO (whose
    read would wait for a writer forever) or a device such as ``/dev/zero`` (endless) is
    refused with :class:`UnreadableText` saying what it is. Raises OSError (missing,
    unreadable) and UnicodeDecodeError as reading would.
    """
    descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    with os.fdopen(descriptor, "rb") as handle:
        kind = file_kind(os.fstat(descriptor).st_mode)
        if kind is not None:
            raise UnreadableText("", f"{path} is {kind}, not a file")
        data = handle.read(MAX_BYTES + 1)
    if len(data) > MAX_BYTES:
        raise UnreadableText("", f"larger than {MAX_BYTES // 1000} kB; a problem file is a few lines")
    return data.decode("utf-8")


def excerpt(value: Any, limit: int = EXCERPT) -> str:
    """``repr(value)`` on one line, cut to about ``limit`` characters."""
    text = _short_repr(value, limit)
    text = text.replace("\r", "\\r").replace("\n", "\\n")
    return text if len(text) <= limit else text[: limit - 3] + "..."


def clip(text: str, limit: int = EXCERPT) -> str:
    """``text`` on one line (runs of white space made one space), cut to ``limit``."""
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _short_repr(value: Any, limit: int) -> str:
    # Never repr a whole container: one built from aliases may be enormous.
    if isinstance(value, (list, tuple)):
        parts, size = [], 0
        for item in value:
            if size > limit:
                parts.append("...")
                break
            parts.append(_short_repr(item, limit))
            size += len(parts[-1]) + 2
        return "[" + ", ".join(parts) + "]"
    if isinstance(value, dict):
        parts, size = [], 0
        for key, item in value.items():
            if size > limit:
                parts.append("...")
                break
            parts.append(f"{_short_repr(key, limit)}: {_short_repr(item, limit)}")
            size += len(parts[-1]) + 2
        return "{" + ", ".join(parts) + "}"
    if isinstance(value, str) and len(value) > limit:
        value = value[:limit]
    return repr(value)


class NonScalarKey:
    """A mapping key written as a list or mapping: kept so the schema can refuse it."""

    def __init__(self, node: yaml.Node):
        self.kind = "list" if isinstance(node, SequenceNode) else "mapping"
        start, end = node.start_mark, node.end_mark
        text = start.buffer[start.index : end.index] if start.buffer is not None else ""
        self.text = clip(text, 30)

    def __str__(self) -> str:
        return self.text

    def __repr__(self) -> str:
        return self.text


class MalformedNumber:
    """A value tagged ``!!int`` or ``!!float`` whose text is no such number: kept (not
    raised while loading, where no key is known) so the schema refuses it by its key."""

    def __init__(self, tag: str, text: str):
        self.text = f"!!{tag} {clip(repr(text), 30)}"

    def __str__(self) -> str:
        return self.text

    def __repr__(self) -> str:
        return self.text


#: YAML 1.1's implicit int and float, as PyYAML's safe loader has them, less base-60
#: numbers: ``1:30`` stays the text it is (which the schema then refuses), not 90.
_INT = re.compile(r"""^(?:[-+]?0b[0-1_]+
                    |[-+]?0[0-7_]+
                    |[-+]?(?:0|[1-9][0-9_]*)
                    |[-+]?0x[0-9a-fA-F_]+)$""", re.X)
_FLOAT = re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+][0-9]+)?
                    |\.[0-9][0-9_]*(?:[eE][-+][0-9]+)?
                    |[-+]?\.(?:inf|Inf|INF)
                    |\.(?:nan|NaN|NAN))$""", re.X)
_NUMBER_TAGS = {"tag:yaml.org,2002:int": _INT, "tag:yaml.org,2002:float": _FLOAT}


def _without_sexagesimal(resolvers: dict) -> dict:
    """``resolvers`` with the int and float patterns replaced by :data:`_INT` and :data:`_FLOAT`."""
    return {first: [(tag, _NUMBER_TAGS.get(tag, pattern)) for tag, pattern in entries]
            for first, entries in resolvers.items()}


class _BoundedLoader(yaml.SafeLoader):
    """YAML's safe loader with strict keys (see the module docstring), and no base-60
    numbers."""

    yaml_implicit_resolvers = _without_sexagesimal(yaml.SafeLoader.yaml_implicit_resolvers)

    def construct_mapping(self, node, deep=False):
        if not isinstance(node, MappingNode):
            return super().construct_mapping(node, deep=deep)
        seen = set()
        for key_node, _ in node.value:
            if isinstance(key_node, ScalarNode) and key_node.tag != _MERGE:
                key = self.construct_object(key_node, deep=deep)
                if key in seen:
                    raise yaml.constructor.ConstructorError(None, None, f"duplicate key {excerpt(key)}", key_node.start_mark)
                seen.add(key)
        self.flatten_mapping(node)  # merged keys first, then the mapping's own: own keys win
        mapping = {}
        for key_node, value_node in node.value:
            if isinstance(key_node, ScalarNode):
                key = self.construct_object(key_node, deep=deep)
            else:
                key = NonScalarKey(key_node)
            mapping[key] = self.construct_object(value_node, deep=deep)
        return mapping

    def construct_yaml_int(self, node):
        try:
            return super().construct_yaml_int(node)
        except (ValueError, IndexError):  # IndexError: PyYAML indexes the empty text
            return MalformedNumber("int", node.value)

    def construct_yaml_float(self, node):
        try:
            return super().construct_yaml_float(node)
        except (ValueError, IndexError):
            return MalformedNumber("float", node.value)


_BoundedLoader.add_constructor("tag:yaml.org,2002:int", _BoundedLoader.construct_yaml_int)
_BoundedLoader.add_constructor("tag:yaml.org,2002:float", _BoundedLoader.construct_yaml_float)


def read_yaml(text: str) -> Any:
    """The single YAML document in ``text`` as plain data (None if it holds nothing).

    Raises :class:`InputError` with a one-line message for text that is too large, does
    not parse, or expands beyond :data:`MAX_VALUES` values or :data:`MAX_DEPTH` levels.
    """
    if len(text.encode("utf-8", "surrogatepass")) > MAX_BYTES:
        raise UnreadableText("", f"larger than {MAX_BYTES // 1000} kB; a problem file is a few lines")
    try:  # the reader refuses control characters (NUL, ESC, DEL, U+FFFE) as it is built
        loader = _BoundedLoader(text)
    except yaml.reader.ReaderError as err:
        line = text.count("\n", 0, err.position) + 1
        raise UnreadableText("", f"malformed YAML at line {line}: character #x{err.character:04x} is not allowed "
                             "(a control character?)") from None
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _check_expansion(node)
        return loader.construct_document(node)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = clip(str(getattr(err, "problem", None) or "cannot parse"), 80)
        raise UnreadableText("", f"malformed YAML{where}: {problem}") from None
    except RecursionError:
        raise UnreadableText("", f"malformed YAML: nested more than {MAX_DEPTH} levels deep") from None
    finally:
        loader.dispose()


def _check_expansion(root: yaml.Node) -> None:
    """Refuse a node graph that, with every alias expanded, is too large, too deep or
    infinite. Sizes are memoised per node, so a file of nested aliases is measured in
    time proportional to its own length."""
    sizes: dict[int, tuple[int, int]] = {}  # id(node) -> (values, depth) when expanded
    active: set[int] = set()

    def measure(node: yaml.Node, level: int) -> tuple[int, int]:
        if level > MAX_DEPTH:
            raise UnreadableText("", f"malformed YAML: nested more than {MAX_DEPTH} levels deep")
        if isinstance(node, ScalarNode):
            return 1, 0
        if id(node) in sizes:
            values, depth = sizes[id(node)]
            if level + depth > MAX_DEPTH:
                raise UnreadableText("", f"malformed YAML: nested more than {MAX_DEPTH} levels deep")
            return values, depth
        if id(node) in active:
            raise UnreadableText("", f"malformed YAML at line {node.start_mark.line + 1}: an alias refers to a value that contains it")
        active.add(id(node))
        children = [n for pair in node.value for n in pair] if isinstance(node, MappingNode) else node.value
        values, depth = 1, 0
        for child in children:
            child_values, child_depth = measure(child, level + 1)
            values, depth = values + child_values, max(depth, child_depth + 1)
            if values > MAX_VALUES:
                raise UnreadableText("", f"YAML expands to more than {MAX_VALUES} values (aliases nested too deeply?)")
        active.discard(id(node))
        sizes[id(node)] = (values, depth)
        return values, depth

    measure(root, 0)
