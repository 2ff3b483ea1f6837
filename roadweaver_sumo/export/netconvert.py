"""Run netconvert on the plain XML from a packaged configuration template.

The filled template is written next to the outputs as ``netconvert.netccfg`` and netconvert runs
inside the scenario folder with relative paths, so ``netconvert -c netconvert.netccfg`` there
reproduces the net, and two runs give byte-identical ``map.net.xml`` once SUMO's timestamp
comment is stripped (see shared NOTES).
"""

from __future__ import annotations

import tempfile
from importlib import resources
from pathlib import Path
from string import Template

from ..errors import RoadweaverError
from ..staging import scratch_dir
from ..sumo_tools import binary, run, strip_generated_comment
from .waiting_points import crowded_connections, wait_at_stop_line

TEMPLATE_PACKAGE = "roadweaver_sumo.netconvert_templates"
CONFIG_NAME = "netconvert.netccfg"
NET_NAME = "map.net.xml"
#: netconvert runs again while connections wait in a foe's path (``waiting_points``), at most
#: this often: moving one car's waiting point to its stop line can move another's onto a foe
#: (learned mixed, density 30, seed 1: one more after 37).
WAIT_ROUNDS = 3
PLAIN_FILES = {
    "node_files": "plain/map.nod.xml",
    "edge_files": "plain/map.edg.xml",
    "connection_files": "plain/map.con.xml",
}


def template_dir():
    """The installed templates, or the repository's ``netconvert_templates/`` when the package
    is imported from a source checkout (a Ray worker started in the checkout does that: the
    package's template subpackage exists only in an installed copy)."""
    try:
        return resources.files(TEMPLATE_PACKAGE)
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[2] / "netconvert_templates"


def available_templates() -> list[str]:
    """Names of the packaged netconvert templates (``urban``, ``suburban``, ...)."""
    files = template_dir().iterdir()
    return sorted(f.name.removesuffix(".netccfg") for f in files if f.name.endswith(".netccfg"))


def fill_template(template: str, walkingareas: bool = False) -> str:
    """The text of template ``template`` with the plain-XML inputs, the net output and
    whether to build walking areas (on maps with sidewalks) filled in."""
    source = template_dir().joinpath(f"{template}.netccfg")
    if not source.is_file():
        choices = ", ".join(available_templates())
        raise RoadweaverError(f"unknown netconvert template {template!r}; choose one of: {choices}")
    try:
        return Template(source.read_text(encoding="utf-8")).substitute(
            PLAIN_FILES, output_file=NET_NAME, walkingareas=str(walkingareas).lower())
    except (KeyError, ValueError) as err:
        msg = f"netconvert template {template!r} has a bad placeholder: {err}"
        raise RoadweaverError(msg) from None


def _run(out_dir: Path) -> None:
    """Run netconvert in ``out_dir``; on failure quote its first ``Error:`` line, which says
    what is wrong (its last line is only "Quitting (on error).").
    The log's folder is in the staging folder when there is one, so a killed run leaves
    nothing elsewhere."""
    with tempfile.TemporaryDirectory(prefix="netconvert-", dir=scratch_dir()) as tmp:
        log = Path(tmp) / "netconvert.log"
        args = [binary("netconvert"), "-c", CONFIG_NAME, "--error-log", str(log)]
        try:
            run(args, cwd=out_dir, what="netconvert")
        except RoadweaverError:
            text = log.read_text(encoding="utf-8", errors="replace") if log.exists() else ""
            errors = [ln[len("Error:") :].strip() for ln in text.splitlines()
                      if ln.startswith("Error:")]
            if not errors:
                raise
            raise RoadweaverError(f"netconvert failed: {errors[0]}") from None


def run_netconvert(out_dir: Path, template: str = "urban", walkingareas: bool = False) -> Path:
    """Build ``out_dir/map.net.xml`` from ``out_dir/plain/`` with the named template (again
    where cars would wait in a foe's path, below); ``walkingareas`` on maps with sidewalks.

    Raises RoadweaverError (one line) when a plain file is missing, the template is unknown or
    netconvert fails; ``--ignore-errors`` is never used, so a net is complete or not written.
    """
    out_dir = Path(out_dir)
    missing = [p for p in PLAIN_FILES.values() if not (out_dir / p).is_file()]
    if missing:
        raise RoadweaverError(f"cannot run netconvert: {out_dir / missing[0]} does not exist")
    (out_dir / CONFIG_NAME).write_text(fill_template(template, walkingareas), encoding="utf-8")
    net = out_dir / NET_NAME
    net.unlink(missing_ok=True)  # never return a net left over from an earlier run
    _run(out_dir)
    if not net.is_file():
        raise RoadweaverError(f"netconvert wrote no {NET_NAME} in {out_dir}")
    for _ in range(WAIT_ROUNDS):  # again, with those cars waiting at the stop line
        crowded = crowded_connections(net)
        if not crowded:
            break
        wait_at_stop_line(out_dir / PLAIN_FILES["connection_files"], crowded)
        net.unlink()
        _run(out_dir)
    strip_generated_comment(net)
    return net
