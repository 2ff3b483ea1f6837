"""One truth, three formats (issue 36): the rules of one map read from ``map.net.xml``,
``map.xodr`` and ``lanelet2_map.osm`` by readers that know nothing of our HD map, matched one
to one: the control of every approach (light, stop, all-way stop, yield), the lanes each light
and sign governs, every "who yields to whom" pair of links, the one-way streets, the
pedestrian crossings (on maps with sidewalks) and each lane's speed limit.
CARLA's map API reads the same signals."""

from __future__ import annotations

from collections import defaultdict

import pytest
from lxml import etree

import roadweaver_sumo as rw
from roadweaver_sumo.export.lanelet2 import LANE_TAG

SIGN_OF = {"traffic_light": "1000001", "stop": "206", "all_way_stop": "206", "yield": "205"}
KIND_OF_SUBTYPE = {"de206": "stop", "de205": "yield"}


@pytest.fixture(scope="module", params=["de", "us", "de+sidewalks", "us+speeds"])
def files(request, tmp_path_factory):
    rules, _, extra = request.param.partition("+")
    speeds = {"arterial": 70.0, "collector": 60.0} if extra == "speeds" else {}
    spec = rw.ScenarioSpec(density=30, vehicles=1, width=1000, height=1000,
                           seed=2 if speeds else 1, skeleton="procedural", rules=rules,
                           sidewalks=extra == "sidewalks", speeds=speeds,
                           roundabouts=3 if speeds else 0)  # seed 2 has room for one
    return {**rw.write_map(rw.generate_map(spec), tmp_path_factory.mktemp(rules)),
            "speeds": speeds}


class Net:
    """What SUMO's net says: per approach (incoming edge) its control, per link (from lane,
    to lane) the links it yields to, per lane its speed."""

    def __init__(self, path):
        root = etree.parse(str(path)).getroot()
        self.speed = {lane.get("id"): float(lane.get("speed")) for edge in root.iter("edge")
                      if edge.get("function") is None for lane in edge.iter("lane")
                      if lane.get("allow") != "pedestrian"}  # sidewalks: no speed limit
        ends = {(e.get("from"), e.get("to")): e.get("id") for e in root.iter("edge")
                if e.get("function") is None}
        self.one_way = {edge for (a, b), edge in ends.items() if (b, a) not in ends}
        function = {e.get("id"): e.get("function") for e in root.iter("edge")}
        self.crossings = {e for e, kind in function.items() if kind == "crossing"}
        by_lane = defaultdict(list)
        for c in root.iter("connection"):  # link indices count pedestrians' links as sumolib
            into, out_of = function[c.get("to")], function[c.get("from")]
            if into != "walkingarea" and (out_of != "walkingarea" or into == "crossing"):
                by_lane[f"{c.get('from')}_{c.get('fromLane')}"].append(c)
        states, self.lit_lanes, self.yields = defaultdict(set), defaultdict(set), {}
        for junction in root.iter("junction"):
            if junction.get("type") == "internal":  # a left turn's waiting point inside
                continue
            links = [c for lane in junction.get("incLanes", "").split() for c in by_lane[lane]]
            responses = [r.get("response") for r in junction.iter("request")]
            keys = [(f"{c.get('from')}_{c.get('fromLane')}", f"{c.get('to')}_{c.get('toLane')}")
                    for c in links]
            for k, (c, key) in enumerate(zip(links, keys, strict=True)):
                if key[0].startswith(":") or key[1].startswith(":"):
                    continue  # a pedestrian's link
                states[c.get("from")].add("tl" if c.get("tl") else c.get("state"))
                if c.get("tl"):
                    self.lit_lanes[c.get("from")].add(key[0])
                bits = responses[k] if k < len(responses) else ""
                self.yields[key] = {keys[j] for j in range(len(bits)) if bits[-(j + 1)] == "1"
                                    and not keys[j][0].startswith(":")}
        self.control = {}
        for edge, seen in states.items():
            kind = ("traffic_light" if "tl" in seen else "all_way_stop" if "w" in seen
                    else "stop" if "s" in seen else "yield" if seen == {"m"} else None)
            if kind:
                self.control[edge] = kind


class Xodr:
    """What the OpenDRIVE file says, translated to SUMO lane ids by the lane numbering rule
    (``f`` lanes are right lanes ``-1..-n``, HD map / SUMO index ``n - |id|``)."""

    def __init__(self, path):
        root = etree.parse(str(path)).getroot()
        roads = {r.get("id"): r for r in root.iter("road")}
        self.crossings = {o.get("id") for o in root.iter("object")
                          if o.get("type") == "crosswalk"}
        self.count = {}  # (road, side) -> lanes on that side
        for rid, road in roads.items():
            for side in ("left", "right"):
                self.count[rid, side] = len(road.findall(f"lanes/laneSection/{side}/lane"))
        self.one_way = {f"r{rid}_{'f' if self.count[rid, 'right'] else 'b'}"
                        for rid, road in roads.items() if road.get("junction") == "-1"
                        and not (self.count[rid, "left"] and self.count[rid, "right"])}
        self.signals, self.signal_lanes, self.speed = {}, {}, {}
        for rid, road in roads.items():
            if road.get("junction") != "-1":
                continue
            for signal in road.iter("signal"):
                direction = "f" if signal.get("orientation") == "+" else "b"
                edge = f"r{rid}_{direction}"
                self.signals[edge] = signal.get("type")
                validity = signal.find("validity")
                ids = range(int(validity.get("fromLane")), int(validity.get("toLane")) + 1)
                self.signal_lanes[edge] = {self.sumo_lane(rid, k) for k in ids}
            for lane in road.iterfind("lanes/laneSection/*/lane"):
                if lane.get("type") == "driving":
                    self.speed[self.sumo_lane(rid, int(lane.get("id")))] = float(
                        lane.find("speed").get("max"))
        self.link = {}  # connecting road id -> (from SUMO lane, to SUMO lane)
        for rid, road in roads.items():
            if road.get("junction") == "-1":
                continue
            pred, succ = road.find("link/predecessor"), road.find("link/successor")
            lane_link = road.find("lanes/laneSection/right/lane/link")
            self.link[rid] = (
                self.sumo_lane(pred.get("elementId"), int(lane_link.find("predecessor").get("id"))),
                self.sumo_lane(succ.get("elementId"), int(lane_link.find("successor").get("id"))))
        self.yields = defaultdict(set)
        for junction in root.iter("junction"):
            for p in junction.iter("priority"):
                self.yields[self.link[p.get("low")]].add(self.link[p.get("high")])

    def sumo_lane(self, road: str, lane: int) -> str:
        side, direction = ("right", "f") if lane < 0 else ("left", "b")
        return f"r{road}_{direction}_{self.count[road, side] - abs(lane)}"


class Lanelet2:
    """What the lanelet2 file says: lanelets by the SUMO lane they stand for (our lane tag
    on road lanelets), connector lanelets by the road lanelets they follow and lead to (shared
    end nodes, as lanelet2 finds them), and the regulatory elements."""

    def __init__(self, path):
        root = etree.parse(str(path)).getroot()
        ways = {w.get("id"): ([nd.get("ref") for nd in w.iter("nd")],
                              {t.get("k"): t.get("v") for t in w.iter("tag")})
                for w in root.iter("way")}
        lanelets, elements, self.crossings = {}, {}, set()
        for rel in root.iter("relation"):
            tags = {t.get("k"): t.get("v") for t in rel.iter("tag")}
            members = [(m.get("role"), m.get("ref")) for m in rel.iter("member")]
            if tags["type"] != "lanelet":
                elements[rel.get("id")] = (tags, members)
            elif tags["subtype"] == "road":  # the pedestrians' lanelets: below
                lanelets[rel.get("id")] = (tags, members)
            elif tags["subtype"] == "crosswalk":
                self.crossings.add(tags[LANE_TAG])
        ends = {}
        for rid, (tags, members) in lanelets.items():
            bound = {role: ways[ref][0] for role, ref in members if role in ("left", "right")}
            ends[rid] = ((bound["left"][0], bound["right"][0]), (bound["left"][-1],
                                                                 bound["right"][-1]))
        road = {rid: tags[LANE_TAG] for rid, (tags, _) in lanelets.items()
                if tags[LANE_TAG].startswith("r")}
        starting = {ends[rid][0]: lane for rid, lane in road.items()}
        ending = {ends[rid][1]: lane for rid, lane in road.items()}
        self.link = {rid: (ending[ends[rid][0]], starting[ends[rid][1]])
                     for rid in lanelets if rid not in road}
        self.speed = {lane: float(lanelets[rid][0]["speed_limit"]) / 3.6
                      for rid, lane in road.items()}
        edges = {lane.rsplit("_", 1)[0] for lane in road.values()}
        self.one_way = {e for e in edges if f"{e[:-1]}{'b' if e[-1] == 'f' else 'f'}" not in edges}
        self.control, self.lanes, self.yields = {}, defaultdict(set), defaultdict(set)
        referring = defaultdict(list)  # regulatory element -> road lanes whose lanelet refers
        for rid, lane in road.items():
            for role, ref in lanelets[rid][1]:
                if role == "regulatory_element":
                    referring[ref].append(lane)
        for eid, (tags, members) in elements.items():
            kind = tags["subtype"]
            if kind == "right_of_way":
                low = [self.link[ref] for role, ref in members if role == "yield"]
                assert len(low) == 1
                self.yields[low[0]] |= {self.link[ref] for role, ref in members
                                        if role == "right_of_way"}
                continue
            if kind == "all_way_stop":
                assert sorted(referring[eid]) == sorted(
                    road[ref] for role, ref in members if role == "yield")
            if kind == "traffic_sign":
                sign = next(ways[ref][1]["subtype"] for role, ref in members if role == "refers")
                kind = KIND_OF_SUBTYPE[sign]
            for lane in referring[eid]:
                edge = lane.rsplit("_", 1)[0]
                self.control[edge] = kind
                self.lanes[edge].add(lane)


def test_the_three_formats_hold_the_same_rules(files):
    net, xodr, osm = Net(files["sumo"]), Xodr(files["opendrive"]), Lanelet2(files["lanelet2"])
    kinds = set(net.control.values())
    assert {"traffic_light", "stop"} <= kinds, kinds
    assert {"yield", "all_way_stop"} & kinds, "de maps have yield signs, us maps all-way stops"
    assert xodr.signals == {edge: SIGN_OF[kind] for edge, kind in net.control.items()}
    assert osm.control == net.control
    for edge, lanes in net.lit_lanes.items():
        assert xodr.signal_lanes[edge] == lanes == osm.lanes[edge], edge
    yielding = {link: foes for link, foes in net.yields.items() if foes}
    assert sum(map(len, yielding.values())) > 50
    assert dict(xodr.yields) == yielding
    assert dict(osm.yields) == yielding
    assert net.one_way and xodr.one_way == net.one_way == osm.one_way
    assert xodr.crossings == net.crossings == osm.crossings  # with --sidewalks: SUMO's
    road_lanes = {lane for lane in net.speed if not lane.startswith(":")}
    assert len(set(net.speed.values())) >= 3, "30, 40 and 50 km/h"
    if files["speeds"]:  # the variant with a roundabout: its entries yield in every format
        assert "<roundabout " in files["sumo"].read_text()
    limits = {round(net.speed[lane] * 3.6) for lane in road_lanes}
    assert limits == {30, 40, 50} if not files["speeds"] else {30, 60, 70}  # --speed
    for lane in road_lanes:
        assert xodr.speed[lane] == pytest.approx(net.speed[lane], abs=0.01), lane
        assert osm.speed[lane] == pytest.approx(net.speed[lane], abs=0.01), lane


def test_carla_reads_the_lights_and_signs(files):
    carla = pytest.importorskip("carla")
    xodr = Xodr(files["opendrive"])
    carla_map = carla.Map("rules", files["opendrive"].read_text())
    landmarks = {(f"r{m.road_id}_{'f' if m.orientation == carla.LandmarkOrientation.Positive else 'b'}"):
                 m.type for m in carla_map.get_all_landmarks()}
    assert landmarks == xodr.signals
    lights = carla_map.get_all_landmarks_of_type("1000001")
    assert lights and all(m.is_dynamic for m in lights)
    assert carla_map.get_all_landmarks_of_type("206"), "stop signs"
