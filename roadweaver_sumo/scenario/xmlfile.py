"""Write XML the way SUMO's own tools do (double-quoted declaration, 4-space indent, final
newline), so our files diff cleanly against SUMO-written ones and are byte-stable."""

from __future__ import annotations

from pathlib import Path

from lxml import etree

DECLARATION = '<?xml version="1.0" encoding="UTF-8"?>\n'


def write_xml(root: etree._Element, path: Path) -> Path:
    """Write the element tree ``root`` to ``path`` as UTF-8 and return the path."""
    etree.indent(root, space="    ")
    text = DECLARATION + etree.tostring(root, encoding="unicode") + "\n"
    Path(path).write_text(text, encoding="utf-8")
    return Path(path)
