"""A minimal XML tree that serialises exactly as lxml's ``pretty_print`` does, several times
faster: the exporters write tens of thousands of elements per km² and lxml's per-element cost
(an attribute dict, a C element, a proxy object) dominated export time on large maps.

Attributes are formatted to text when an element is created, so an element is just a tag, one
string and its children; a childless element may even be given as its finished text
(:func:`leaf`), and a whole subtree that repeats thousands of times as its finished lines
(:class:`Block`). Only what the exporters use is supported: attributes, children, and a text or
CDATA child of a childless element.
"""

from __future__ import annotations

from pathlib import Path

_ESCAPES = str.maketrans({"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;",
                          "\n": "&#10;", "\r": "&#13;", "\t": "&#9;"})
DECLARATION = "<?xml version='1.0' encoding='UTF-8'?>\n"  # what lxml's write() puts first


class Element:
    """One element: ``tag``, its attributes as ready text (`` k="v"`` ...), children, text."""

    __slots__ = ("attrs", "children", "tag", "text")

    def __init__(self, tag: str, attrs: str = "") -> None:
        self.tag, self.attrs, self.children, self.text = tag, attrs, [], None

    def append(self, child: Element) -> None:
        self.children.append(child)

    def extend(self, children) -> None:
        self.children.extend(children)


class Block(str):
    """A finished subtree as text: its lines joined by newlines, indented relative to the
    block's first line with the indent of the file it goes into. Written with each line
    moved to the block's place in the tree."""

    __slots__ = ()


class PlacedBlock:
    """A :class:`Block` whose lines after the first already carry the indent of the place it
    is written to: written as it is, where a Block of a million lines would be re-indented
    line by line. It holds its text rather than being a str: a str subclass copies the text
    it is made from, 50 MB for the nodes of a 10 km lanelet2 map. The text may also be ASCII
    bytes (any bytes-like object: a compiled writer's output), written to the file as they
    are, neither decoded nor encoded again."""

    __slots__ = ("text",)

    def __init__(self, text: str | bytes | memoryview) -> None:
        self.text = text


def escape(value: str) -> str:
    """An attribute value escaped as lxml escapes it."""
    return value.translate(_ESCAPES)


def attr_text(attrs) -> str:
    """`` k="v"`` for each (key, value string) pair; values are escaped."""
    return "".join(f' {k}="{v.translate(_ESCAPES)}"' for k, v in attrs)


def sub(parent: Element, tag: str, attrs: str = "") -> Element:
    """A new child of ``parent`` with attribute text ``attrs`` (see :func:`attr_text`)."""
    child = Element(tag, attrs)
    parent.children.append(child)
    return child


def leaf(tag: str, attrs: str = "") -> str:
    """A childless element as finished text, to append where an :class:`Element` would go."""
    return f"<{tag}{attrs}/>"


def cdata(text: str) -> str:
    """Element text written as a CDATA section."""
    return f"<![CDATA[{text}]]>"


def to_text(root: Element, indent: str) -> str:
    """The tree as pretty-printed text (no declaration), ending without a newline, the way
    ``etree.indent(root, indent)`` then ``etree.tostring`` writes it."""
    return "".join(piece if type(piece) is str else str(piece, "ascii")
                   for piece in _pieces(root, indent))[:-1]


def _pieces(root: Element, indent: str) -> list[str]:
    """The tree's text in pieces, each line ending in a newline; a placed block is a piece of
    its own, never copied (bytes if its text is)."""
    out: list[str] = []
    _write(root, "", indent, out)
    return out


def _write(elem: Element, pad: str, indent: str, out: list[str]) -> None:
    if elem.children:
        out.append(f"{pad}<{elem.tag}{elem.attrs}>\n")
        inner = pad + indent
        for child in elem.children:
            if type(child) is str:
                out.append(f"{inner}{child}\n")
            elif type(child) is Block:
                out += (inner, child.replace("\n", "\n" + inner), "\n")
            elif type(child) is PlacedBlock:
                out += (inner, child.text, "\n")
            elif child.children:
                _write(child, inner, indent, out)
            elif child.text is None:
                out.append(f"{inner}<{child.tag}{child.attrs}/>\n")
            else:
                out.append(f"{inner}<{child.tag}{child.attrs}>{child.text}</{child.tag}>\n")
        out.append(f"{pad}</{elem.tag}>\n")
    elif elem.text is None:
        out.append(f"{pad}<{elem.tag}{elem.attrs}/>\n")
    else:
        out.append(f"{pad}<{elem.tag}{elem.attrs}>{elem.text}</{elem.tag}>\n")


#: Pieces written per call, joined (each call costs as much as ~2 kB of text), unless one of
#: them is large or bytes (a placed block): that batch is written piece by piece, uncopied.
_BATCH, _LARGE = 1024, 1 << 16


def write(root: Element, path: Path, indent: str = "  ", declaration: str = DECLARATION) -> Path:
    """Write ``root`` after ``declaration`` with a final newline (lxml ``write(pretty_print=True,
    xml_declaration=True, encoding="UTF-8")`` output for the default arguments). In batches of
    pieces: joined into one string, the 100 MB of a 10 km map's lanelet2 file took a third
    more time in copies and fresh memory; written one by one, the 275k pieces of its
    OpenDRIVE file took twice as long as in batches."""
    path = Path(path)
    pieces = _pieces(root, indent)
    with path.open("w", encoding="utf-8") as file:
        file.write(declaration)
        for start in range(0, len(pieces), _BATCH):
            batch = pieces[start:start + _BATCH]
            if max(map(len, batch)) < _LARGE and set(map(type, batch)) == {str}:
                file.write("".join(batch))
                continue
            for piece in batch:
                if type(piece) is str:
                    file.write(piece)
                else:  # ASCII bytes: to the file's bytes, after the text before them
                    file.flush()
                    file.buffer.write(piece)
    return path
