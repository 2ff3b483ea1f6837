"""The command line's arguments: every option with its type, range, default and choices, so
that ``--help`` states them and a bad value is a one-line error before any work starts.

make-scenario's and make-suite's values are checked where the spec is made (``spec.py``, also
used for manifests); the ranges here are those of the other commands.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from . import __version__
from .errors import RoadweaverError
from .spec import (
    BOUNDARIES,
    DEFAULT_BUS_LINES,
    DEFAULT_EGO_LENGTH_M,
    DEFAULT_GEO_ORIGIN,
    DEFAULT_ONE_WAY_SHARE,
    DEFAULT_PERSONS,
    DEFAULT_ROUNDABOUTS,
    DEFAULT_RULES,
    DEFAULT_VEHICLE_MIX,
    DEPARTURES,
    MAX_BUS_LINES,
    MAX_DENSITY,
    MAX_DURATION_S,
    MAX_EGO_LENGTH_M,
    MAX_EGO_ROUTES,
    MAX_FRINGE_FACTOR,
    MAX_LANES,
    MAX_ROUNDABOUTS,
    MAX_SEED,
    MAX_SIDE_M,
    MAX_VEHICLES,
    MAX_WORKERS,
    MIN_DURATION_S,
    MIN_EGO_LENGTH_M,
    MIN_ROAD_NODES,
    MIN_SIDE_M,
    MIX_CONTROLS,
    PRIOR_RANGES,
    RULES,
    SKELETONS,
    STYLES,
)

PROG = "roadweaver-sumo"
EXIT_FAILED_CHECKS, EXIT_BAD_INPUT, EXIT_INTERNAL_ERROR = 1, 2, 3  # see cli's docstring
RULES_HELP = ("regional traffic rules that choose each junction's control: de (right-before-left "
              "in residential streets, stop signs onto arterials), us (all-way stops, stop "
              "signs), priority (yield at every junction without a light)")
MIX_HELP = ("vehicle classes and their shares of the trips, SUMO's classes with SUMO's default "
            "types: passenger, truck, bus, motorcycle, bicycle, delivery")
DEFAULT_MIX_TEXT = ",".join(f"{k}:{v:g}" for k, v in DEFAULT_VEHICLE_MIX.items())
FRINGE_HELP = ("randomTrips' --fringe-factor: trips start and end this many times likelier where "
               "roads leave an open map")
ONE_WAY_HELP = ("share of the local street length made one-way: streets followed straight "
                "through junctions, neighbours in opposite directions (one-way pairs)")
DEPARTURES_HELP = "random: uniform random departure times (randomTrips --random-depart); even"
BOUNDARY_HELP = ("open: roads run off the map edge, as in a map cut out of a town; ring: a ring "
                 "road just inside the border closes the map")
#: what each structural prior of the learned model's condition means (data/condition.py)
PRIOR_HELP = {
    "gridness": "how grid-like the streets are (orientation order and square crossings; "
                "presets: grid 0.67, mixed 0.31, organic 0.07)",
    "radialness": "how much streets run along or across the radius from the densest centre "
                  "(radial preset 0.19, others about 0)",
    "organicness": "how much streets curve (presets: grid 0.10, mixed 0.41, organic 0.80)",
    "bearing_entropy": "spread of street directions in nats (presets: grid 2.06, mixed 2.98, "
                       "organic 3.47)",
}
# data prepare: a tile is cut from one town, and its raster is what the models train on
MIN_TILE_M, MAX_TILE_M = 200.0, 20_000.0
MIN_CELLS, MAX_CELLS = 8, 512  # the VQ-VAE downsamples by 8
# train
MAX_STEPS, MAX_BATCH, MAX_LR = 10_000_000, 4096, 1.0


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage error in one line instead of usage text plus error, and
    shows defaults in ``--help``."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        raise RoadweaverError(message)


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """``(default: X)`` after every option with a default worth stating (not None or False)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        if action.default is None or action.default is False or not action.help:
            return action.help or ""
        return super()._get_help_string(action)


def _number(kind: type, low: float, high: float, *, above: bool = False):
    """An argparse type: a finite ``kind`` (int or float) from ``low`` (excluded with
    ``above``) to ``high``; anything else is a one-line error that states the range."""
    what = "a whole number" if kind is int else "a number"
    if math.isinf(high):
        span = f"{'>' if above else '>='} {low:g} and finite"
    else:
        span = f"> {low:g} and <= {high:g}" if above else f"{low:g}..{high:g}"

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {what} ({span})") from None
        if not math.isfinite(value) or value < low or value > high or (above and value == low):
            raise argparse.ArgumentTypeError(f"must be {span}, got {text}")
        return value

    return parse


def _choices(names) -> str:
    return "{" + ",".join(names) + "}"


SEED = _number(int, 0, MAX_SEED)
SEED_HELP = f"random seed, 0..{MAX_SEED}"
SIZE_HELP = (f"map size in metres, 2000 or 3000x2000; each side {MIN_SIDE_M:g}..{MAX_SIDE_M:g}")
VEHICLES_HELP = f"vehicles, 1..{MAX_VEHICLES}"
DURATION_HELP = (f"demand horizon in seconds, {MIN_DURATION_S:g}..{MAX_DURATION_S:g} (a week)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog=PROG, description="Lane-level road networks as SUMO scenarios.")
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    make = sub.add_parser("make-scenario", help="generate a map and a validated SUMO scenario")
    make.add_argument("--density", type=float,
                      help=f"road nodes per km², > 0 and <= {MAX_DENSITY:g}; the map must hold "
                           f"at least {MIN_ROAD_NODES} road nodes (required unless --like gives "
                           "the city's)")
    vehicles = make.add_mutually_exclusive_group(required=True)
    vehicles.add_argument("--vehicles", type=int, help=VEHICLES_HELP)
    vehicles.add_argument("--insertion-rate", type=_number(float, 0.0, MAX_VEHICLES, above=True),
                          metavar="PER_HOUR", help="vehicles per hour, as randomTrips' "
                          "--insertion-rate: --vehicles is this rate over --duration")
    make.add_argument("--size", default="2000", help=SIZE_HELP)
    make.add_argument("--seed", type=int, default=0,
                      help=f"{SEED_HELP} (SUMO's tools take 32-bit seeds)")
    make.add_argument("--style", default="mixed", metavar=_choices(STYLES), help="road style")
    make.add_argument("--skeleton", default="learned", metavar=_choices(SKELETONS),
                      help="how the arterial roads are made")
    make.add_argument("--boundary", default="open", metavar=_choices(BOUNDARIES),
                      help=BOUNDARY_HELP)
    _add_rule_and_demand_options(make)
    make.add_argument("--geo-origin", default=",".join(f"{v:g}" for v in DEFAULT_GEO_ORIGIN),
                      metavar="LAT,LON", help="WGS84 position of the map's origin (its "
                      "south-west corner) in every format's geo-reference")
    make.add_argument("--duration", type=float, default=3600.0, help=DURATION_HELP)
    make.add_argument("--like", type=Path, metavar="FILE",
                      help="a map like this road network: an OpenStreetMap extract (.osm, "
                           ".osm.gz, .osm.bz2, .osm.pbf), a SUMO .net.xml or an osmnx .graphml; "
                           "its priors condition the learned skeleton, its density is used "
                           "unless --density is given, and the report says how close the map "
                           "came")
    for name, what in PRIOR_HELP.items():
        low, high = PRIOR_RANGES[name]
        make.add_argument(f"--{name.replace('_', '-')}", type=_number(float, low, high),
                          help=f"{low:g}..{high:g}: {what} (default: the style's or the "
                               "--like city's; learned skeleton only)")
    make.add_argument("--ego-routes", type=_number(int, 0, MAX_EGO_ROUTES), default=0,
                      help=f"long routes for an ego vehicle, 0..{MAX_EGO_ROUTES}, written as "
                           "ego_routes.rou.xml and routes.json for 'drive'")
    make.add_argument("--ego-length", type=_number(float, MIN_EGO_LENGTH_M, MAX_EGO_LENGTH_M),
                      default=DEFAULT_EGO_LENGTH_M,
                      help=f"length of each ego route in metres (± 10 %%), "
                           f"{MIN_EGO_LENGTH_M:g}..{MAX_EGO_LENGTH_M:g}")
    make.add_argument("--out", type=Path, help="output folder (default ./scenarios/<name>)")
    make.add_argument("--force", action="store_true", help="replace an existing output folder")
    make.add_argument("--no-validate", action="store_true", help="skip the libsumo validation")
    make.add_argument("--json", action="store_true", help="print the report as JSON")

    data = sub.add_parser("data", help="training data for the learned skeleton")
    data_sub = data.add_subparsers(dest="data_command", required=True, parser_class=_Parser)
    prep = data_sub.add_parser("prepare", help="cut OSM files into road-field tiles")
    prep.add_argument("--osm", type=Path, nargs="+", required=True,
                      help=".osm, .osm.gz, .osm.bz2 or .osm.pbf files")
    prep.add_argument("--out", type=Path, required=True, help="dataset folder")
    prep.add_argument("--tile", type=_number(float, MIN_TILE_M, MAX_TILE_M), default=2000.0,
                      help=f"tile side in metres, {MIN_TILE_M:g}..{MAX_TILE_M:g}")
    prep.add_argument("--size", type=_number(int, MIN_CELLS, MAX_CELLS), default=128,
                      help=f"raster cells per tile side, {MIN_CELLS}..{MAX_CELLS}, a multiple "
                           "of 8")
    prep.add_argument("--seed", type=SEED, default=0, help=SEED_HELP)
    prep.add_argument("--force", action="store_true", help="replace an existing dataset folder")

    drive = sub.add_parser("drive", help="drive a controller along an ego route and score it")
    drive.add_argument("dir", type=Path, metavar="DIR", help="a scenario made with --ego-routes")
    drive.add_argument("--route", type=_number(int, 0, MAX_EGO_ROUTES), default=0,
                       help="which ego route (routes.json)")
    drive.add_argument("--controller",
                       help="sumo (SUMO's own driver, the default), naive (ignores signals and "
                            "limits) or module:function (your controller: observation dict -> "
                            "action dict)")
    drive.add_argument("--remote-port", type=_number(int, 1024, 65535),
                       help="let a stack in another process drive the ego over TraCI: SUMO "
                            "serves this port, the stack connects as client 2 (traci.init, "
                            "traci.setOrder(2)) and controls vehicle 'ego'")
    drive.add_argument("--out", type=Path,
                       help="drive report file (default DIR/drive_report_<route>.json)")
    drive.add_argument("--json", action="store_true", help="print the drive report as JSON")

    val = sub.add_parser("validate", help="re-run the validation of a scenario folder")
    val.add_argument("dir", type=Path)
    val.add_argument("--json", action="store_true", help="print the report as JSON")
    _add_suite_commands(sub, make)
    ev = sub.add_parser("evaluate", help="our metrics for any SUMO network")
    ev.add_argument("net", type=Path, metavar="NET.net.xml")
    ev.add_argument("--area-km2", type=_number(float, 0, math.inf, above=True),
                    help="map area in km², > 0 (default: the net's convBoundary)")
    ev.add_argument("--json", action="store_true", help="print the metrics as JSON")
    _add_train_commands(sub)
    return parser


def _add_rule_and_demand_options(parser: argparse.ArgumentParser) -> None:
    """``--rules``, ``--one-way-share``, ``--sidewalks``, ``--persons``, ``--bus-lines``,
    ``--vehicle-mix``,
    ``--departures`` and ``--fringe-factor``: the same for
    a scenario and for every scenario of a suite."""
    parser.add_argument("--rules", default=DEFAULT_RULES, metavar=_choices(RULES),
                        help=RULES_HELP)
    parser.add_argument("--one-way-share", type=_number(float, 0.0, 1.0),
                        default=DEFAULT_ONE_WAY_SHARE, help=ONE_WAY_HELP)
    parser.add_argument("--sidewalks", action=argparse.BooleanOptionalAction, default=True,
                        help="a 2 m sidewalk beside every driving direction and a pedestrian "
                             "crossing over every road at junctions of three or more roads "
                             "(default: on)")
    parser.add_argument("--persons", type=_number(int, 0, MAX_VEHICLES), default=None,
                        help="pedestrians walking 100-1000 m (at most 2.5 km on foot) on the "
                             f"sidewalks over --duration (default: {DEFAULT_PERSONS}, none with "
                             "--no-sidewalks)")
    parser.add_argument("--bus-lines", type=_number(int, 0, MAX_BUS_LINES), default=None,
                        help=f"bus lines across the map along its main roads, both ways, a bus "
                             f"every 10 minutes, stops every 400 m, 0..{MAX_BUS_LINES} (default: "
                             f"{DEFAULT_BUS_LINES} where the main roads have room for it)")
    parser.add_argument("--vehicle-mix", default=DEFAULT_MIX_TEXT, help=MIX_HELP)
    parser.add_argument("--departures", default="random", metavar=_choices(DEPARTURES),
                        help=DEPARTURES_HELP)
    parser.add_argument("--fringe-factor", type=_number(float, 0.0, MAX_FRINGE_FACTOR),
                        default=1.0, help=FRINGE_HELP)
    parser.add_argument("--roundabouts", type=_number(int, 0, MAX_ROUNDABOUTS),
                        default=DEFAULT_ROUNDABOUTS,
                        help="up to this many junctions where collectors meet become "
                             "roundabouts (3 or 4 arms, no light, room for a 15 m ring)")
    parser.add_argument("--speed", metavar="CLASS=KMH[,CLASS=KMH]",
                        help="speed limits by road class, as netgenerate's --speed gives one "
                             "for all, e.g. arterial=70,local=30; each 5..130 km/h (default: "
                             "arterial 50, collector 40, local 30)")
    parser.add_argument("--lanes", metavar="CLASS=N[,CLASS=N]",
                        help="driving lanes per direction by road class, as netgenerate's "
                             f"--lanenumber gives one count for all, e.g. arterial=3; each "
                             f"1..{MAX_LANES}; a road that would come within another's "
                             "clearance keeps its class's (default: arterial 2, collector 1, "
                             "local 1)")
    parser.add_argument("--junction-mix", metavar="CONTROL=SHARE[,CONTROL=SHARE]",
                        help="shares of the junctions of three or more arms by control, of "
                             f"{', '.join(MIX_CONTROLS)}, e.g. traffic_light=0.2,"
                             "allway_stop=0.3; lights and signs go to the most major "
                             "junctions, right-before-left and all-way stops to the most "
                             "minor; the rest follow --rules (default: all follow --rules)")


def _add_suite_commands(sub, make: argparse.ArgumentParser) -> None:
    """``make-suite``, ``check-suite`` and ``render`` (scenario suites and previews)."""
    suite = sub.add_parser("make-suite", help="build a grid of scenarios with a manifest")
    suite.add_argument("--densities", required=True,
                       help=f"road nodes per km², each > 0 and <= {MAX_DENSITY:g}, e.g. 10,20,30")
    suite.add_argument("--styles", default="mixed",
                       help=f"comma-separated, from {_choices(STYLES)}")
    suite.add_argument("--seeds", default="0",
                       help=f"seeds and ranges, e.g. 0-9 or 0,3,7; each 0..{MAX_SEED}")
    suite.add_argument("--size", default="2000", help=SIZE_HELP)
    suite.add_argument("--vehicles", type=int, default=500, help=f"{VEHICLES_HELP} per scenario")
    suite.add_argument("--duration", type=float, default=3600.0, help=DURATION_HELP)
    suite.add_argument("--skeleton", default=make.get_default("skeleton"),
                       metavar=_choices(SKELETONS),
                       help="how the arterial roads are made")  # same default as make-scenario
    suite.add_argument("--boundary", default=make.get_default("boundary"),
                       metavar=_choices(BOUNDARIES), help=BOUNDARY_HELP)
    _add_rule_and_demand_options(suite)
    suite.add_argument("--ego-routes", type=_number(int, 0, MAX_EGO_ROUTES), default=0,
                       help="ego routes per scenario, for 'drive-suite'")
    suite.add_argument("--ego-length", type=_number(float, MIN_EGO_LENGTH_M, MAX_EGO_LENGTH_M),
                       default=make.get_default("ego_length"),
                       help="length of each ego route in metres (± 10 %%)")
    suite.add_argument("--min-coverage", metavar="KIND=N[,KIND=N]",
                       help="every scenario holds at least N of each rule situation (a junction "
                       "control such as traffic_light or allway_stop, roundabouts, "
                       "roundabout_entries, one_way_edges, turn_bays, protected_lefts, "
                       "pedestrian_crossings, speed_limit_changes, bus_stops); one that "
                       "falls short is built again with its next seed (+1000), up to 8 times")
    suite.add_argument("--out", type=Path, required=True, help="suite folder")
    suite.add_argument("--force", action="store_true", help="replace an existing suite folder")
    suite.add_argument("--engine", default="local", metavar="{local,ray}",
                       help="local (process pool) or ray")
    suite.add_argument("--address", help="Ray cluster address (with --engine ray)")
    suite.add_argument("--workers", type=int,
                       help=f"parallel scenarios, 1..{MAX_WORKERS} (default: CPU count)")
    suite.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    suite.add_argument("--json", action="store_true", help="print the summary as JSON")

    check = sub.add_parser("check-suite", help="check a suite against its manifest")
    check.add_argument("dir", type=Path)
    check.add_argument("--no-regenerate", action="store_true",
                       help="only re-validate; do not rebuild every scenario to compare hashes")
    check.add_argument("--workers", type=int,
                       help=f"parallel scenarios, 1..{MAX_WORKERS} (default: CPU count)")
    check.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    check.add_argument("--json", action="store_true", help="print the result as JSON")

    drive = sub.add_parser("drive-suite", help="drive a controller along every ego route of "
                           "a suite: a score table, and its changes against a baseline table")
    drive.add_argument("dir", type=Path, metavar="SUITE", help="a suite made with --ego-routes")
    drive.add_argument("--controller", default="sumo", help="as for 'drive'")
    drive.add_argument("--out", type=Path,
                       help="score table to write (default SUITE/drive_scores.json)")
    drive.add_argument("--baseline", type=Path,
                       help="an earlier score table: list what changed, exit 1 if a route "
                            "scores lower or has an infraction it did not have")
    drive.add_argument("--force", action="store_true", help="replace an existing score table")
    drive.add_argument("--json", action="store_true", help="print the score table as JSON")

    render = sub.add_parser("render", help="redraw preview.png of scenario folders")
    render.add_argument("dirs", type=Path, nargs="+", metavar="DIR")


def _add_train_commands(sub) -> None:
    """``train vqvae``, ``train maskgit`` and ``train distil`` (the learned skeleton, paper
    §III-B; distil: the transformer's guidance, so sampling needs one pass per step)."""
    from .generative.settings import DISTIL_SETTINGS, MASKGIT_SETTINGS, VQVAE_SETTINGS

    train = sub.add_parser("train", help="train the learned skeleton's models")
    kinds = train.add_subparsers(dest="model", required=True, parser_class=_Parser)
    for name, defaults, what in (
            ("vqvae", VQVAE_SETTINGS, "train the VQ-VAE"),
            ("maskgit", MASKGIT_SETTINGS, "train the masked transformer"),
            ("distil", DISTIL_SETTINGS, "distil a trained transformer's guidance into a copy")):
        p = kinds.add_parser(name, help=f"{what} on a prepared dataset")
        p.add_argument("--data", type=Path, required=True, help="folder from 'data prepare'")
        if name != "vqvae":
            p.add_argument("--vqvae", type=Path, required=True, help="trained VQ-VAE checkpoint")
        if name == "distil":
            p.add_argument("--teacher", type=Path, required=True,
                           help="trained transformer checkpoint (from 'train maskgit')")
        p.add_argument("--out", type=Path, required=True, help="checkpoint file to write")
        p.add_argument("--steps", type=_number(int, 1, MAX_STEPS), default=defaults.steps,
                       help=f"training steps, 1..{MAX_STEPS}")
        p.add_argument("--batch", type=_number(int, 1, MAX_BATCH), default=defaults.batch,
                       help=f"tiles per step, 1..{MAX_BATCH}")
        p.add_argument("--lr", type=_number(float, 0, MAX_LR, above=True), default=defaults.lr,
                       help=f"learning rate, > 0 and <= {MAX_LR:g}")
        p.add_argument("--seed", type=SEED, default=defaults.seed, help=SEED_HELP)
        p.add_argument("--force", action="store_true", help="replace an existing checkpoint")
        p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
