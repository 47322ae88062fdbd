"""The exploration simulator, free of Gymnasium: teleport → scan → update map, statistics and
navigation → ΔQ (docs/protocol.md). The environment (:mod:`nbv_gym.env`) and the CLI wrap it.

What a team of robots shares — the world, the map, the statistics, the quality — is an
:class:`Exploration`; what each robot owns is its :class:`~nbv_gym.core.robot.Robot`. The
:class:`Simulator` is the team of one; :mod:`nbv_gym.team` runs several robots on one
:class:`Exploration`."""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import cast

import numpy as np

from nbv_gym.core.errors import ConfigError, NbvGymError
from nbv_gym.core.grid import GridSpec
from nbv_gym.core.pose import Pose
from nbv_gym.core.progress import say_if_compiling
from nbv_gym.core.protocol import EpisodeConfig, check_noise_level
from nbv_gym.core.robot import Robot
from nbv_gym.mapping import (
    ExplorationState,
    MappingConfig,
    NavigationLayer,
    OccupancyMap,
    ViewpointStatistics,
)
from nbv_gym.mapping.mapfile import save_map
from nbv_gym.mapping.scratch import ScanTrial
from nbv_gym.mapping.store import BLOCK
from nbv_gym.mapping.tally import CellTally
from nbv_gym.metrics.cuboids import CuboidConfig, QualityConfig, QualitySummary
from nbv_gym.metrics.tracker import QualityTracker
from nbv_gym.sensor.lidar import Lidar, LidarConfig, Scan
from nbv_gym.worlds import World, WorldSpec, load_spec, load_world
from nbv_gym.worlds.scenes import SceneSpec

#: The most memory one simulator's episode may need by :func:`episode_memory_bytes` (bytes); a
#: world or episode estimated above it is refused before the episode starts.
MAX_EPISODE_BYTES = 4 << 30
#: Measured costs behind :func:`episode_memory_bytes` (a 1000-tree 500 m world, Linux): the
#: interpreter with numpy, numba and Embree; Embree's acceleration structure per triangle; the
#: statistics, tally, quality and navigation arrays per cell of G.
PROCESS_BYTES = 320 << 20
EMBREE_BYTES_PER_TRIANGLE = 80
BYTES_PER_G_CELL = 256


class EpisodeMemoryError(NbvGymError, MemoryError):
    """An episode whose estimated memory exceeds :data:`MAX_EPISODE_BYTES`."""


class InvalidActionError(NbvGymError, ValueError):
    """A goal that is not a valid action now; the message says why."""


class ResetNeededError(NbvGymError, RuntimeError):
    """A step before the first reset or after the episode ended (Gymnasium: reset first)."""


def goal_index(action: object, n_goals: int) -> int:
    """``action`` as a goal index in [0, ``n_goals``): a Python or numpy integer, or a 0-d
    integer array. Anything else (bool, float, NaN, str, a 1-element list or array) raises
    :class:`InvalidActionError` naming what came — nothing is rounded or converted."""
    value = action
    if isinstance(action, np.ndarray) and action.ndim == 0 and action.dtype.kind in "iu":
        value = action.item()
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise InvalidActionError(
            f"A goal is an integer index in [0, {n_goals}), got {_describe(action)}. "
            "Give an integer, e.g. int(np.argmax(scores))."
        )
    if not 0 <= value < n_goals:
        raise InvalidActionError(f"A goal is an integer index in [0, {n_goals}), got {value}.")
    return int(value)


def _describe(value: object) -> str:
    if isinstance(value, np.ndarray):
        return f"a {value.dtype} array of shape {value.shape}"
    return f"{type(value).__name__} {value!r}"


@dataclass(frozen=True)
class SimulatorConfig:
    """Everything one exploration episode depends on, besides the seed and the policy.

    ``world`` is a benchmark world name or a spec file path; ``noise`` the localisation-noise
    level, one of :data:`~nbv_gym.core.protocol.NOISE_LEVELS` (docs/protocol.md#lidar).
    """

    world: str = "pp1-trees"
    noise: int = 1
    lidar: LidarConfig = field(default_factory=LidarConfig)
    mapping: MappingConfig = field(default_factory=MappingConfig)
    quality: QualityConfig = field(default_factory=QualityConfig)
    episode: EpisodeConfig = field(default_factory=EpisodeConfig)

    def __post_init__(self) -> None:
        check_noise_level(self.noise)


@dataclass(frozen=True)
class StepOutcome:
    """What a reset or a step produced.

    ``quality`` is the map quality after the scan; ``reward`` = ``delta_q`` (weighted by the
    share of the budget left in the time task) − path penalty;
    ``path_length_m`` the length of this step's path; ``terminated``/``truncated`` as in
    Gymnasium, with ``reason`` saying why the episode ended ("" while it runs); ``touched``
    (nx, ny, nz) bool the cells of G whose map voxels the scan changed.
    """

    scan: Scan
    touched: np.ndarray
    quality: QualitySummary
    delta_q: float
    reward: float
    path_length_m: float
    discovered: float
    terminated: bool
    truncated: bool
    reason: str


class Exploration:
    """What a team of robots shares exploring one world: the world and its lidar, the map, the
    viewpoint statistics G and the navigation layer (:class:`ExplorationState`), and the map
    quality. What each robot owns — pose, clock, noise generator — is its
    :class:`~nbv_gym.core.robot.Robot`: :meth:`sense` scans from a robot's pose with its
    generator into the shared map. The navigation layer is planned for one robot at a time, the
    one that decides next (:meth:`sense` plans for the robot that scanned, :meth:`plan` for
    another). :class:`Simulator` is the team of one."""

    def __init__(self, config: SimulatorConfig | None = None, world: World | None = None):
        config = config or SimulatorConfig()
        spec = world.spec if world is not None else load_spec(config.world)
        if world is None and isinstance(spec, SceneSpec):  # its window is the built scene's
            world = load_world(spec)
        window = world.window_m if world is not None else cast(WorldSpec, spec).window_m
        config = replace(config, mapping=config.mapping.fitted(window))
        self.config = config  # with the map box and G fitted to the world
        say_if_compiling()
        self.goal_grid = self.config.mapping.statistics.grid()
        self._check_world(world or spec)
        self.world = world or load_world(spec)
        self._check_memory(self.world)
        self.lidar = Lidar.for_world(self.world, self.config.lidar, self.config.noise)
        self.voxel_grid = self.config.mapping.scored_grid()
        self.quality = self._quality_tracker(self.world)
        self.goal_centres = self.goal_grid.xy_centres()
        band = (self.config.quality.unknown_low, self.config.quality.unknown_high)
        thresholds = tuple(p for p, _ in self.config.quality.cov_settings)
        self._state = ExplorationState.from_config(self.config.mapping, band, thresholds)
        self.state: ExplorationState | None = None  # the episode's state; None before a reset
        self._unobserved = self.summary = self.quality.summary()  # of every cuboid unobserved

    def set_world(self, world: World) -> None:
        """Explore ``world`` from the next reset on (e.g. a world distribution's next
        draw), keeping this simulator's grids and map arrays; the previous world's scene and
        ground truth are released. ConfigError unless its placement window lies in G."""
        self._check_world(world)
        self._check_memory(world)
        self.world = world
        self.lidar = Lidar.for_world(world, self.config.lidar, self.config.noise)
        self.quality = self._quality_tracker(world)
        self._unobserved = self.summary = self.quality.summary()
        self.state = None

    def _check_memory(self, world: World) -> None:
        """EpisodeMemoryError if an episode on ``world`` may need more than
        :data:`MAX_EPISODE_BYTES` (:func:`episode_memory_bytes`), naming the estimate, the limit
        and the longest episode that fits."""
        config = self.config
        need = episode_memory_bytes(world, config.mapping, config.episode.max_steps + 1)
        if need <= MAX_EPISODE_BYTES:
            return
        fixed = episode_memory_bytes(world, config.mapping, 0)
        fits = (MAX_EPISODE_BYTES - fixed) // map_page_bytes(config.mapping, 1) - 1  # steps
        advice = (
            f"lower episode.max_steps to {fits} or less, or use a smaller placement window"
            if fits >= 1
            else "use a smaller placement window or fewer assets"
        )
        raise EpisodeMemoryError(
            f"an episode of {config.episode.max_steps} steps on world {world.name} may need "
            f"{need / 2**30:.1f} GiB, more than the limit of {MAX_EPISODE_BYTES / 2**30:g} GiB "
            f"(nbv_gym.simulator.MAX_EPISODE_BYTES); {advice}"
        )

    def _check_world(self, world) -> None:
        """ConfigError unless the window of ``world`` (a built world or a procedural spec) lies
        in G."""
        low, high = tuple(self.goal_grid.low[:2]), tuple(self.goal_grid.high[:2])
        mapping = self.config.mapping
        fits = f"fitted to windows of at most mapping.max_window_m = {mapping.max_window_m:g} m"
        what = fits if mapping.fit_to_world else "mapping.fit_to_world = false"
        world.check_inside(low, high, f"the goal grid (mapping.statistics; {what})")

    @property
    def n_goals(self) -> int:
        """Number of goals (actions): the x, y cells of G."""
        return len(self.goal_centres)

    @property
    def _live(self) -> ExplorationState:
        """The episode's state; :class:`ResetNeededError` before a reset."""
        if self.state is None:
            raise ResetNeededError("Call reset() first.")
        return self.state

    @property
    def navigation(self) -> NavigationLayer:
        """The navigation layer of the current episode."""
        return self._state.navigation

    @property
    def statistics(self) -> ViewpointStatistics:
        """The viewpoint statistics G of the current episode."""
        return self._state.statistics

    @property
    def occupancy(self) -> OccupancyMap:
        """The occupancy map of the current episode."""
        return self._state.occupancy

    def save(self, folder: str | Path) -> None:
        """Write the map (``map.npz``) and the statistics (``statistics.npz``) to ``folder``."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        world = f"{self.world.name}@{self.world.spec.digest()}"
        save_map(self.occupancy, folder / "map.npz", world, self.world.file_frame())
        self.statistics.save(folder / "statistics.npz")

    def clear(self) -> None:
        """Start an episode's shared state: the map, statistics and quality arrays of the
        previous episode are cleared and reused."""
        self._state.clear()
        self.state = self._state
        self.quality.reset()
        self.summary = self._unobserved

    def sense(self, robot: Robot, remaining_s: float) -> tuple[Scan, np.ndarray, float]:
        """``robot`` scans from its pose with its generator: the map, statistics and quality
        are updated, and the navigation layer planned for ``robot`` with ``remaining_s``
        seconds left on its clock. The scan, the (nx, ny, nz) bool cells of G whose map voxels
        it changed, and the change of Q."""
        scan = self.lidar.scan(robot.pose, robot.rng)
        state = self._live
        update = state.apply(scan, robot_xy=robot.xy)
        state.navigation.limit_reach(self.config.episode.budget.reach_m(remaining_s))
        before = self.summary
        self.summary = self._update_quality(update.touched_cells)
        return scan, update.touched, self.summary.q - before.q

    def plan(self, robot: Robot, remaining_s: float, excluded: np.ndarray) -> None:
        """Plan the navigation layer for ``robot`` with ``remaining_s`` seconds left, the
        (k,) goals ``excluded`` not valid (e.g. teammates' goals)."""
        navigation = self._live.navigation
        navigation.plan(robot.xy)
        navigation.limit_reach(self.config.episode.budget.reach_m(remaining_s))
        navigation.exclude_goals(excluded)

    def pose_at(self, goal: int, origin: Pose) -> Pose:
        """A robot's ground pose after teleporting from ``origin`` to ``goal``: its cell
        centre, heading along the move."""
        x, y = self.goal_centres[goal]
        yaw = math.atan2(y - origin.y, x - origin.x)
        return Pose(float(x), float(y), 0.0, yaw)

    def reward(self, delta_q: float, path_length_m: float, remaining_s: float) -> float:
        """ΔQ, weighted in the time task by the share of the budget left after the scan
        (``remaining_s``; the robot holds the gain that long: an episode's rewards, the first
        scan's included, sum to its area under Q(t) over the budget), minus the path
        penalty."""
        episode = self.config.episode
        return (
            delta_q * episode.budget.held(remaining_s) - episode.path_penalty_per_m * path_length_m
        )

    def _update_quality(self, touched: np.ndarray) -> QualitySummary:
        state = self._live
        if state.tally is None:  # the simulator builds its state with an unobserved band
            raise NbvGymError("the quality update needs the map's cell totals")
        return update_quality(self.quality, state.tally, state.occupancy, self.goal_grid, touched)

    def ending(self, robot: Robot, remaining_s: float) -> tuple[bool, bool, str]:
        """Whether the episode ends for ``robot`` (the planned one, with ``remaining_s``
        seconds left): terminated, truncated and why ("" while it runs)."""
        episode = self.config.episode
        target = episode.discovered_target
        discovered = self._live.navigation.discovered_fraction
        if target is not None and discovered >= target:
            return True, False, f"discovered {discovered:.1%} ≥ {target:.0%}"
        if robot.steps >= episode.max_steps:
            return False, True, f"reached max_steps = {episode.max_steps}"
        if not self._live.navigation.goal_mask().any():
            if self.config.episode.budget.limited and self._time_bound():
                return False, True, self._spent(robot, remaining_s)
            return False, True, "no valid goal is reachable"
        return False, False, ""

    def _spent(self, robot: Robot, remaining_s: float) -> str:
        """Why a time budget ended the episode for ``robot``; at its first scan, with what the
        nearest goal would have taken."""
        if robot.steps:
            return f"time budget spent ({remaining_s:.1f} s left)"
        navigation, effort = self._live.navigation, self.config.episode.effort
        nearest = float(navigation.goal_path_length()[navigation.goal_mask(limited=False)].min())
        return (
            f"time budget spent at the first scan: time_budget_s = "
            f"{self.config.episode.time_budget_s:g} s leaves no goal (the nearest takes "
            f"{effort.elapsed_s(nearest, 1):.1f} s: {nearest:.1f} m at {effort.speed_mps:g} m/s "
            f"and a scan of {effort.scan_time_s:g} s)"
        )

    def _time_bound(self) -> bool:
        """Whether the time budget is what leaves no valid goal in the current plan: some goal
        would be valid with unlimited time."""
        navigation = self._live.navigation
        return bool(navigation.goal_mask(limited=False).any())

    def check_goal(self, goal: int, remaining_s: float) -> None:
        """:class:`InvalidActionError` saying why unless ``goal`` is valid in the current plan
        (with ``remaining_s`` seconds left on the planned robot's clock)."""
        if self._live.navigation.goal_mask()[goal]:
            return
        x, y = self.goal_centres[goal]
        raise InvalidActionError(
            f"Goal {int(goal)} at ({x:.1f}, {y:.1f}) m is not valid now: "
            f"{self._invalid_reason(int(goal), remaining_s)}. Choose a goal where "
            "info['action_mask'] is True."
        )

    def _invalid_reason(self, goal: int, remaining_s: float) -> str:
        navigation = self._live.navigation
        if goal == navigation.robot_goal:
            return "it is the robot's own cell"
        if goal in navigation.excluded_goals:
            return "a teammate stands on it or drives to it"
        x, y = self.goal_centres[goal]
        (x0, y0), (x1, y1) = self.goal_grid.low[:2], self.goal_grid.high[:2]
        margin = self.config.mapping.navigation.border_margin_m
        if min(x - x0, x1 - x, y - y0, y1 - y) < margin:
            return f"it lies within {margin} m of the window border"
        path_m = navigation.goal_path_length()[goal]
        if not np.isfinite(path_m):
            return "it is not known free space reachable from the robot"
        if not self.config.episode.budget.fits(path_m, remaining_s):
            cost = self.config.episode.effort.elapsed_s(path_m, 1)
            return f"driving there and scanning takes {cost:.1f} s, {remaining_s:.1f} s are left"
        return "it is not a valid goal"

    def start_pose(self) -> Pose:
        """The episode config's start pose (on the ground)."""
        episode = self.config.episode
        return Pose(*episode.start_xy_m, 0.0, episode.start_yaw_rad)

    def _quality_tracker(self, world: World) -> QualityTracker:
        """The quality tracker of ``world``: its ground-truth lists, built once per world, on
        G's cells at the map's voxels, with the map's lower clamp."""
        mapping = self.config.mapping
        config = CuboidConfig.for_map(
            self.config.quality,
            mapping.map.resolution_m,
            mapping.statistics.cell_m,
            mapping.map.p_clamp_min,
        )
        voxels = scored_voxels(world, self.voxel_grid)
        return QualityTracker.from_voxels(voxels, self.voxel_grid.shape, config)


class Simulator(Exploration):
    """One robot exploring one world, the team of one (:class:`Exploration` holds what a team
    shares, :attr:`robot` what the robot owns). ``reset(seed)`` starts an episode with the
    first scan; ``step(goal)`` teleports to a goal cell, scans and updates everything."""

    def __init__(self, config: SimulatorConfig | None = None, world: World | None = None):
        super().__init__(config, world)
        self.robot = Robot(self.start_pose())
        self.ended = ""  # why the episode ended; "" while it runs

    @property
    def pose(self) -> Pose:
        """The robot's pose."""
        return self.robot.pose

    @property
    def rng(self) -> np.random.Generator:
        """The robot's generator of localisation and range noise."""
        return self.robot.rng

    @property
    def trajectory(self) -> list[Pose]:
        """The robot's scan poses, the first scan's included."""
        return self.robot.trajectory

    @property
    def steps(self) -> int:
        """The robot's scans after the first one."""
        return self.robot.steps

    @property
    def path_length_m(self) -> float:
        """The robot's path, metres."""
        return self.robot.path_length_m

    @property
    def elapsed_s(self) -> float:
        """The robot's clock: seconds spent since the first scan under the episode's effort model
        (path driven / speed + scans after the first × scan time)."""
        return self.robot.elapsed_s(self.config.episode.effort)

    @property
    def remaining_s(self) -> float:
        """Seconds left of the episode's time budget (inf without one)."""
        return self.robot.remaining_s(self.config.episode.budget)

    def reset(self, seed: int | None = None) -> StepOutcome:
        """Start an episode at the start pose and take the first scan; randomness from ``seed``.
        The map, statistics and quality arrays of the previous episode are cleared and reused.
        An episode can end at its first scan (``reason`` set: e.g. a time budget that leaves no
        goal); :meth:`step` then refuses, saying why."""
        self.robot.reset(seed)
        self.clear()
        self.ended = ""
        outcome = self._observe(path_length_m=0.0)
        self.ended = outcome.reason
        return outcome

    def step(self, goal: int) -> StepOutcome:
        """Teleport to ``goal`` (index into the goal grid), scan, update; raises
        :class:`InvalidActionError` for a goal that is not a valid action now (see
        :func:`goal_index`) and :class:`ResetNeededError` before a reset or after the end."""
        if self.state is None:
            raise ResetNeededError("Call reset() before step().")
        if self.ended:
            when = "at its first scan, before any step " if self.steps == 0 else ""
            raise ResetNeededError(
                f"The episode has ended {when}({self.ended}); call reset() before step() again"
                f"{' (with a larger budget: the same one ends the same way)' if when else ''}."
            )
        goal = goal_index(goal, self.n_goals)
        self.check_goal(goal, self.remaining_s)
        path_length = float(self.state.navigation.goal_path_length()[goal])
        self.robot.move(self.goal_pose(goal), path_length)
        self.robot.goal = goal
        outcome = self._observe(path_length)
        self.ended = outcome.reason
        return outcome

    def goal_mask(self) -> np.ndarray:
        """(n_goals,) bool: the goals that are valid actions now."""
        return self._live.navigation.goal_mask()

    def goal_pose(self, goal: int) -> Pose:
        """The robot's ground pose after teleporting to ``goal``: its cell centre, heading along
        the move from the current pose."""
        return self.pose_at(goal, self.pose)

    def _observe(self, path_length_m: float) -> StepOutcome:
        """Scan from the current pose, update map, statistics, navigation and quality."""
        remaining = self.remaining_s
        scan, touched, delta_q = self.sense(self.robot, remaining)
        reward = self.reward(delta_q, path_length_m, remaining)
        discovered = self._live.navigation.discovered_fraction
        terminated, truncated, reason = self.ending(self.robot, remaining)
        return StepOutcome(
            scan,
            touched,
            self.summary,
            delta_q,
            reward,
            path_length_m,
            discovered,
            terminated,
            truncated,
            reason,
        )


def episode_memory_bytes(world: World, mapping: MappingConfig, n_scans: int) -> int:
    """An upper estimate of a simulator's memory (bytes) for an episode of ``n_scans`` scans on
    ``world`` with the (fitted) ``mapping`` config: the process, the world's arrays and Embree's
    copy and acceleration structure of its mesh, the per-cell arrays of G, and the map's pages —
    at most those of the whole map box, and at most those of the sensor's marking window per
    scan (a scan writes no voxel outside it)."""
    mesh = world.vertices.nbytes + world.faces.nbytes
    world_bytes = 2 * mesh + 2 * world.ground_truth.voxels.nbytes
    embree = EMBREE_BYTES_PER_TRIANGLE * len(world.faces)
    cells = int(np.prod(mapping.statistics.grid().shape))
    return (
        PROCESS_BYTES
        + world_bytes
        + embree
        + BYTES_PER_G_CELL * cells
        + map_page_bytes(mapping, n_scans)
    )


def map_page_bytes(mapping: MappingConfig, n_scans: int) -> int:
    """The most bytes of map pages ``n_scans`` scans make resident: the bricks of the map box,
    at most those overlapping the marking window of each scan (one brick more per axis, as the
    window need not start on a brick)."""
    box, window = OccupancyMap.brick_counts(mapping.map.grid(), mapping.sensor_range_m)
    return BLOCK * 4 * min(int(np.prod(box)), n_scans * int(np.prod(window)))


def update_quality(
    tracker: QualityTracker,
    tally: CellTally,
    occupancy: OccupancyMap,
    grid: GridSpec,
    touched: np.ndarray,
) -> QualitySummary:
    """Recompute the metrics of the (k,) flat ``touched`` cuboids (cells of ``grid``, G) only:
    from the map's running totals (``tally``), and the voxels of those whose coverage must be
    searched again (a voxel crossed a coverage threshold: the tally's crossed cells, taken)."""
    sums, outside = tally.sums.reshape(-1)[touched], tally.outside.reshape(-1)[touched]
    search = tracker.needs_coverage(tally.take_crossed())
    levels = occupancy.level_blocks(grid, grid.unravel(search), tracker.bounds)
    return tracker.update_totals(touched, sums, outside, search, levels)


class Lookahead:
    """The true ΔQ of a scan from each of some goals, evaluated without committing it: the
    simulator's state, quality and generator are left as they are (an oracle's evaluation).

    The scan from goal g is the very scan :meth:`Simulator.step` to g would take next: the same
    pose (:meth:`Simulator.goal_pose`) and a copy of the simulator's generator, hence the same
    localisation and range noise. It is inserted into a scratch copy of the map and cell totals
    (:class:`~nbv_gym.mapping.scratch.ScanTrial`), its ΔQ read from a scratch quality tracker,
    then both are restored (the map by undoing the blocks the trial wrote). Build one after each reset (a new world changes the tracker).
    """

    def __init__(self, sim: Simulator):
        if sim.state is None:
            raise ResetNeededError("Call reset() before building a Lookahead.")
        self.sim = sim
        self.trial = ScanTrial(sim.state)
        self.tracker = sim.quality.scratch()

    def delta_q(self, goals: np.ndarray) -> np.ndarray:
        """(m,) float64 ΔQ of a scan from each of the (m,) goal indices ``goals``."""
        sim = self.sim
        self.trial.restore()
        self.tracker.restore(sim.quality)
        out = np.empty(len(goals))
        for index, goal in enumerate(np.asarray(goals, np.int64)):
            scan = sim.lidar.scan(sim.goal_pose(int(goal)), copy.deepcopy(sim.rng))
            update = self.trial.insert(scan.origin, scan.points_map)
            trial = self.trial
            after = update_quality(
                self.tracker, trial.tally, trial.map, sim.goal_grid, update.touched_cells
            )
            out[index] = after.q - sim.summary.q
            self.trial.undo()
            self.tracker.restore(sim.quality)
        return out


def scored_voxels(world: World, grid: GridSpec | None = None) -> np.ndarray:
    """(k, 3) int64 indices into ``grid`` of the ground-truth voxels of ``world`` that map
    quality scores (``grid``: where it is scored; by default the default mapping config's,
    fitted to the world); ConfigError, naming the box, when there is none (Q would be
    undefined)."""
    grid = grid or MappingConfig().fitted(world.window_m).scored_grid()
    voxels = world.ground_truth.grid_voxels(grid)
    if len(voxels) == 0:
        (x0, y0, z0), (x1, y1, z1) = grid.low, grid.high
        raise ConfigError(
            f"world {world.name} has no ground-truth voxel in the box where map quality is "
            f"scored (x {x0:g} to {x1:g} m, y {y0:g} to {y1:g} m, z {z0:g} to {z1:g} m; "
            "mapping.statistics): Q would be undefined. Its surfaces must rise above "
            f"z = {z0:g} m inside that box"
        )
    return voxels
