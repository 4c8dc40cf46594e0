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
    def translation_sd_m(self) -> float: ...
    @property
    def rotation_sd_deg(self) -> float: ...
    @property
    def covariance(self) -> Optional[F64]: ...  # (6, 6): (tx, ty, tz [m], rx, ry, rz [rad])

def read_map(
    path: PathLike,
    min_observations: int = 2,
    format: str = "auto",  # auto, lmalign, bundler, colmap-text, colmap-bin, ply, stella-vslam
    image_size: Optional[Tuple[int, int]] = None,  # (width, height) px, Bundler only
) -> Map: ...
def write_map(path: PathLike, map: Map) -> None: ...
def strategies() -> List[str]: ...
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
