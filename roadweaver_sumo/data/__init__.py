"""Real road data for training the skeleton model (issue 4): any user's OSM extract to tiles,
road fields F and condition vectors c (paper §III-B).

``osm`` reads and simplifies the drivable network, ``tiles`` cuts and augments square tiles,
``field`` rasterises a tile graph into F and vectorises F back into a graph, ``condition`` and
``style_code`` measure c, ``prepare`` writes a dataset. Road data © OpenStreetMap contributors
(ODbL): anything derived from OSM input must carry that attribution (``prepare.ATTRIBUTION``).
"""

from .condition import CONDITION_NAMES, condition_vector, structural_priors
from .field import CHANNELS, FIELD_SIZE, field_to_graph, road_field, rotate_field
from .graphml import read_graphml
from .osm import read_osm
from .prepare import ATTRIBUTION, decode_field, load_dataset, prepare_dataset
from .style_code import STYLE_FEATURES, style_code
from .tiles import Tile, cut_tile, iter_tiles

__all__ = [
    "ATTRIBUTION", "CHANNELS", "CONDITION_NAMES", "FIELD_SIZE", "STYLE_FEATURES", "Tile",
    "condition_vector", "cut_tile", "decode_field", "field_to_graph", "iter_tiles",
    "load_dataset", "prepare_dataset", "read_graphml", "read_osm", "road_field", "rotate_field",
    "structural_priors", "style_code",
]
