# Type stubs of the lmalign package (docs/python.md). Shapes in comments: float64 arrays,
# metres, m^2; T_target_source maps source coordinates to target coordinates.
import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str
RECOMMENDED_STRATEGY: str

ArrayLike = npt.ArrayLike
PathLike = Union[str, os.PathLike]
F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]

class Error(Exception): ...
class InvalidArgument(Error, ValueError): ...
class IoError(Error, OSError): ...
class ParseError(Error, ValueError):
    file: str
    line: int  # 1-based; 0 = the file as a whole
    detail: str

class Map:
    @property
    def positions(self) -> F64: ...  # (N, 3) p_world, m
    @property
    def covariances(self) -> F64: ...  # (N, 3, 3) world frame, m^2
    @property
    def observation_counts(self) -> I64: ...  # (N,)
    @property
    def scale(self) -> str: ...  # 'metric', 'arbitrary' or 'unknown'
    @property
    def covariance_assumed(self) -> bool: ...
    @property
    def landmark_ids(self) -> I64: ...  # (N,)
    @property
    def frame_ids(self) -> I64: ...  # (F,)
    @property
    def frame_poses(self) -> F64: ...  # (F, 4, 4) T_world_camera
    @property
    def num_frames(self) -> int: ...
    def __len__(self) -> int: ...  # landmarks
    def transformed(self, T_new_old: ArrayLike) -> Map: ...

class AlignmentResult:
    @property
    def T_target_source(self) -> F64: ...  # (4, 4), p_target = T @ p_source
    @property
    def strategy(self) -> str: ...
    @property
    def converged(self) -> bool: ...
    @property
    def termination(self) -> str: ...
    @property
    def iterations(self) -> int: ...
    @property
    def num_correspondences(self) -> int: ...
    @property
    def initial_score_m2(self) -> float: ...
    @property
    def final_score_m2(self) -> float: ...
    @property
    def wall_time_s(self) -> float: ...
    @property
    def started_s(self) -> float: ...  # time.monotonic() clock
    @property
    def finished_s(self) -> float: ...
    @property
    def trustworthy(self) -> bool: ...
    @property
    def trust_reason(self) -> str: ...
    @property
    def source_landmarks_left_out(self) -> int: ...  # beyond the supported range (1e15 m)
    @property
    def target_landmarks_left_out(self) -> int: ...
    @property
    def covariances_assumed(self) -> bool: ...
    @property
    def inlier_fraction(self) -> Optional[float]: ...
    @property
    def overlap_fraction(self) -> Optional[float]: ...
    @property
    def gated_inlier_ratio(self) -> Optional[float]: ...
    @property
    def ambiguity(self) -> Optional[float]: ...
    @property
    def mean_nis(self) -> Optional[float]: ...
    @property
    def covariance_scale(self) -> Optional[float]: ...
    @property
    def alias_waived_by_prior(self) -> Optional[bool]: ...
    @property
    def rival_T_target_source(self) -> Optional[np.ndarray]: ...
    @property
    def translation_sd_m(self) -> float: ...
    @property
    def rotation_sd_deg(self) -> float: ...
    @property
    def covariance(self) -> Optional[F64]: ...  # (6, 6): (tx, ty, tz [m], rx, ry, rz [rad])
    @property
    def scale(self) -> float: ...  # target units per source unit (1.0 when fixed)
    @property
    def scale_sd(self) -> Optional[float]: ...
    @property
    def scale_mode(self) -> str: ...  # "free" or "fixed"
    @property
    def S_target_source(self) -> F64: ...  # (4, 4) [scale * R, t; 0 1]
    @property
    def usable(self) -> bool: ...
    def brief_report(self) -> str: ...
    def full_report(self) -> str: ...
    def to_json(self, indent: int = -1) -> str: ...

def read_map(
    path: PathLike,
    min_observations: int = 2,
    format: str = "auto",  # "auto" or a name of map_formats()
    image_size: Optional[Tuple[int, int]] = None,  # (width, height) px, Bundler: top-left pixels
) -> Map: ...
def write_map(path: PathLike, map: Map) -> None: ...
def map_formats() -> List[Dict[str, Union[str, bool]]]: ...  # name, doc, detected_by, writes
def strategies() -> List[str]: ...
def options(strategy: str) -> List[Dict[str, str]]: ...  # key, value, unit, bound, doc
def align(
    source: Union[Map, ArrayLike],  # Map or (N, 3)
    target: Union[Map, ArrayLike],  # Map or (M, 3)
    strategy: str = ...,
    initial_guess: Optional[ArrayLike] = None,  # (4, 4) T_target_source
    threads: int = 0,
    *,
    prior_sigma: Optional[ArrayLike] = None,  # (rot_deg, trans_m)
    source_covariances: Optional[ArrayLike] = None,  # (N, 3, 3) m^2
    target_covariances: Optional[ArrayLike] = None,  # (M, 3, 3) m^2
    target_weights: Optional[ArrayLike] = None,  # (M,)
    k: int = 5,
    max_iterations: Optional[int] = None,
    max_distance_m: Optional[float] = None,
    covariance_norm: str = "spectral",
    settings: Optional[Dict[str, Any]] = None,  # key -> value (lmalign.options(strategy))
    scale: str = "auto",  # auto, free or fixed
) -> AlignmentResult: ...
def split(
    map: Map,
    first_frame_id: int,
    last_frame_id: int,
    min_observations: int = 2,
    retriangulate: bool = False,
    min_parallax_deg: float = 2.0,
    return_stats: bool = False,
) -> Union[Map, Tuple[Map, Dict[str, int]]]: ...
def experiment(
    config: PathLike,
    output_dir: PathLike,
    only: Optional[Sequence[str]] = None,
    threads: int = 0,
    data_dir: Optional[PathLike] = None,
    plots: bool = False,
) -> Dict[str, Any]: ...
def read_tum_trajectory(path: PathLike) -> Tuple[F64, F64]: ...  # (N,) s, (N, 4, 4) T_world_camera
def evaluate_trajectory(
    estimate: Union[str, Tuple[ArrayLike, ArrayLike]],
    ground_truth: Union[str, Tuple[ArrayLike, ArrayLike]],
    max_difference_s: float = 0.02,
    offset_s: float = 0.0,
    delta_s: float = 1.0,
    align: bool = True,
) -> Dict[str, Any]: ...
def pose_from_xyz_rpy_deg(
    x_m: float, y_m: float, z_m: float, roll_deg: float, pitch_deg: float, yaw_deg: float
) -> F64: ...  # (4, 4)
def transform_points(T: ArrayLike, points: ArrayLike) -> F64: ...  # (N, 3)
def transform_covariances(T: ArrayLike, covariances: ArrayLike) -> F64: ...  # (N, 3, 3)

# ---- merge (docs/merge.md): present only when HAVE_MERGE (lmalign::merge built, Ceres found)
HAVE_MERGE: bool
MERGE_NAMES: Tuple[str, ...]

class MapPrior:
    def __init__(self, T_world_map: ArrayLike, covariance: ArrayLike) -> None: ...
    @property
    def T_world_map(self) -> F64: ...  # (4, 4) p_world = T @ p_map, m
    @property
    def scale(self) -> float: ...  # world units per map unit (1: rigid prior)
    @property
    def covariance(self) -> F64: ...  # (6, 6) (rho m, phi rad), left, world frame

class ManifestEntry:
    @property
    def name(self) -> str: ...
    @property
    def path(self) -> str: ...
    @property
    def format(self) -> str: ...
    @property
    def session(self) -> str: ...
    @property
    def prior(self) -> Optional[MapPrior]: ...

class Manifest:
    @property
    def file(self) -> str: ...
    @property
    def maps(self) -> List[ManifestEntry]: ...
    @property
    def names(self) -> List[str]: ...
    @property
    def priors(self) -> List[Optional[MapPrior]]: ...

class CandidatePair:
    def __init__(
        self,
        source: int,
        target: int,
        initial_guess: Optional[ArrayLike] = None,  # (4, 4) T_target_source
        prior_sigma: Optional[ArrayLike] = None,  # (rot_deg, trans_m)
    ) -> None: ...
    @property
    def source(self) -> int: ...
    @property
    def target(self) -> int: ...
    @property
    def rank(self) -> float: ...
    @property
    def initial_guess(self) -> Optional[F64]: ...  # (4, 4)
    @property
    def source_metric(self) -> bool: ...
    @property
    def target_metric(self) -> bool: ...
    @property
    def prior_sigma(self) -> Optional[Tuple[float, float]]: ...
    @property
    def prior_complete_search(self) -> str: ...  # 'rescue' or 'check'
    @property
    def complete_search(self) -> str: ...  # without a prior: 'rescue' or 'check'
    @property
    def verified_matches(self) -> int: ...  # the largest clique of the retrieval's verification

class Edge:
    @property
    def source(self) -> int: ...
    @property
    def target(self) -> int: ...
    @property
    def T_target_source(self) -> F64: ...  # (4, 4) m
    @property
    def covariance(self) -> F64: ...  # (6, 6) (rho m, phi rad), left, target frame
    @property
    def covariance_valid(self) -> bool: ...
    @property
    def trusted(self) -> bool: ...
    @property
    def trust_reason(self) -> str: ...
    @property
    def num_inliers(self) -> int: ...
    @property
    def inlier_ratio(self) -> float: ...
    @property
    def initialisation(self) -> str: ...  # global, prior, given, ...
    @property
    def scale_free(self) -> bool: ...  # the alignment estimated the scale (Sim(3))
    @property
    def scale(self) -> float: ...  # target units per source unit (1: rigid)
    @property
    def scale_sd(self) -> float: ...  # NaN when fixed
    @property
    def summary_json(self) -> str: ...  # AlignmentResult.to_json()'s serialisation
    @property
    def key(self) -> str: ...
    def with_key(self, key: str) -> Edge: ...

class MapPose:
    @property
    def T_world_map(self) -> F64: ...  # (4, 4) m
    @property
    def covariance(self) -> F64: ...  # (6, 6)
    @property
    def covariance_valid(self) -> bool: ...
    @property
    def component(self) -> int: ...
    @property
    def is_gauge(self) -> bool: ...
    @property
    def scale(self) -> float: ...  # world units per map unit (1: metric)
    @property
    def scale_sd(self) -> float: ...  # 0 when held
    @property
    def scale_free(self) -> bool: ...

class EdgeReport:
    @property
    def used(self) -> bool: ...
    @property
    def rejected(self) -> bool: ...
    @property
    def chi2(self) -> float: ...
    @property
    def skip_reason(self) -> str: ...
    @property
    def reject_reason(self) -> str: ...

class PoseGraphResult:
    @property
    def maps(self) -> List[MapPose]: ...
    @property
    def edges(self) -> List[EdgeReport]: ...
    @property
    def num_components(self) -> int: ...
    @property
    def final_chi2(self) -> float: ...
    @property
    def edge_covariance_scale(self) -> float: ...
    @property
    def rounds(self) -> int: ...
    @property
    def converged(self) -> bool: ...

class MergeOutcome:
    names: List[str]
    T_world_map: F64  # (N, 4, 4) p_world = T @ p_map, m
    covariances: F64  # (N, 6, 6) (rho m, phi rad), left, world frame
    scales: F64  # (N,) world units per map unit (1: metric, or scale='fixed')
    components: I64  # (N,)
    is_gauge: npt.NDArray[np.bool_]  # (N,)
    candidates: List[CandidatePair]
    edges: List[Edge]
    trusted: npt.NDArray[np.bool_]  # (E,)
    used: npt.NDArray[np.bool_]  # (E,)
    rejected: npt.NDArray[np.bool_]  # (E,)
    chi2: F64  # (E,)
    num_components: int
    final_chi2: float
    edge_covariance_scale: float
    graph: PoseGraphResult
    evaluation: Optional[Dict[str, Any]]
    backend: str  # 'in-process' or 'dask'
    edges_reused: int
    seconds_edges: float
    seconds_graph: float
    output_dir: str

def read_manifest(path: PathLike) -> Manifest: ...
def load_manifest_maps(manifest: Manifest) -> List[Map]: ...
def read_manifest_map(entry: ManifestEntry) -> Map: ...
def plan_candidates(
    maps: Sequence[Map],
    priors: Optional[Sequence[Optional[MapPrior]]] = None,
    *,
    max_pairs: int = 0,
    keep_per_map: int = 4,
    all_pairs_max_maps: int = 12,
    verify_per_map: int = 200,
) -> List[CandidatePair]: ...
def align_edge(
    source: Map,
    target: Map,
    pair: CandidatePair,
    max_iterations: Optional[int] = None,
    *,
    scale: str = "auto",  # auto, free, fixed
) -> Edge: ...
def map_fingerprint(map: Map) -> str: ...
def edge_key(
    source_fingerprint: str,
    target_fingerprint: str,
    pair: CandidatePair,
    max_iterations: Optional[int] = None,
    *,
    scale: str = "auto",  # auto, free, fixed
) -> str: ...
def edge_file_path(dir: PathLike, source_name: str, target_name: str) -> str: ...
def write_edge_file(path: PathLike, edge: Edge) -> None: ...
def read_edge_file(path: PathLike) -> Optional[Edge]: ...
def solve_pose_graph(
    num_maps: int,
    priors: Optional[Sequence[Optional[MapPrior]]],
    edges: Sequence[Edge],
    *,
    maps: Optional[Sequence[Map]] = None,  # their headers: which have no metric scale
    scale: str = "auto",  # auto, free, fixed
    overlap_check: str = "repair",  # repair, check, off (with maps)
) -> PoseGraphResult: ...
class OverlapCheck:
    @property
    def reference_agreement(self) -> float: ...
    @property
    def contradicted_per_map(self) -> List[int]: ...
    @property
    def contradicted_per_component(self) -> List[int]: ...
    @property
    def pairs(self) -> List[Tuple[int, int, int, int, float, bool, bool]]: ...
    def num_contradicted(self) -> int: ...

def check_overlaps(
    maps: Sequence[Map],
    result: PoseGraphResult,
    edges: Sequence[Edge],
    *,
    threads: int = 0,
) -> OverlapCheck: ...
def write_merge_outputs(
    out_dir: PathLike,
    names: Sequence[str],
    sessions: Sequence[str],
    maps: Sequence[Map],
    edges: Sequence[Edge],
    result: PoseGraphResult,
    fuse_landmarks: bool = True,
    overlaps: Optional[OverlapCheck] = None,
) -> None: ...
def read_ground_truth(path: PathLike, names: Sequence[str]) -> F64: ...  # (N, 4, 4)
def evaluate_merge(
    result: PoseGraphResult,
    edges: Sequence[Edge],
    truth: ArrayLike,  # (N, 4, 4) T_world_map_true
    rotation_deg: float = 5.0,
    translation_m: float = 0.10,
) -> Dict[str, Any]: ...
def merge(
    manifest_path: PathLike,
    output_dir: PathLike,
    *,
    ground_truth: Optional[Union[str, PathLike]] = None,  # 'identity' or a YAML file
    max_pairs: Optional[int] = None,
    threads: Optional[int] = None,
    dask_client: Optional[Any] = None,  # distributed.Client
    resume: bool = False,
    thresholds: Tuple[float, float] = (5.0, 0.10),  # (rot_deg, trans_m)
    fuse_landmarks: bool = True,
    scale: str = "auto",  # auto, free, fixed
    plots: bool = False,  # merge_graph.png, merged_landmarks.png (matplotlib)
    overlap_check: str = "repair",  # repair, check, off
) -> MergeOutcome: ...
