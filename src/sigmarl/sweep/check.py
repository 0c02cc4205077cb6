"""`sigmarl sweep --check`: a study checked before it trains, in this process, leaving nothing
behind (no plan file, run folder, Hydra folder or tracker record).

Beyond what planning checks (every job composed, its config and scenarios checked), it loads
every map, training maps and scenarios' alike, builds each scenario's environment once and each
training configuration's learner once, and times them here: a few test steps of each scenario
and one training iteration (its collection and GAE whole, one of its epochs scaled to all of
them). Anything that would fail later fails here, in one line.
"""

from __future__ import annotations

import resource
import time
from dataclasses import dataclass, replace
from pathlib import Path

from sigmarl.compose import compose_config
from sigmarl.config import Config
from sigmarl.errors import SigmarlError
from sigmarl.sweep.plan import SweepPlan, plan_sweep

TEST_STEPS = 5  # timed steps of each scenario's test environment


def _clock() -> float:
    """This process's CPU seconds: a job's compute on a free core, whatever else loads the
    machine now (on a GPU, the host's share only: an estimate for a CPU study)."""
    return time.process_time()


@dataclass
class Costs:
    iteration_s: dict[str, float]  # training fingerprint -> seconds per iteration
    step_s: dict[str, float]  # scenario -> seconds per test step (all its simulations at once)
    peak_mib: float  # this process's peak resident memory once everything was built and run


def check_sweep(user_overrides: list[str]) -> int:
    """Plan, build and time the sweep; print its jobs with their estimated costs."""
    start = time.perf_counter()
    plan = plan_sweep(user_overrides)
    configs = {job.label: compose_config(job.overrides) for job in plan.jobs}  # one per variant: a seed's is alike
    costs = measure(configs)
    for line in report_lines(plan, configs, costs, time.perf_counter() - start):
        print(line)
    return 0


def measure(configs: dict[str, Config]) -> Costs:
    """Every map loaded, every scenario and training set-up built and timed; one line on failure."""
    import torch

    from sigmarl.resources import use_threads

    use_threads(next(iter(configs.values())).threads)
    torch.manual_seed(0)
    step_s: dict[str, float] = {}
    iteration_s: dict[str, float] = {}
    for label, cfg in configs.items():
        for name in cfg.eval.scenarios:
            if name not in step_s:
                step_s[name] = _guarded(f"scenario {name}", _time_scenario, cfg, name)
        if cfg.driver.kind == "mappo" and cfg.fingerprint not in iteration_s:
            iteration_s[cfg.fingerprint] = _guarded(f"variant {label}'s training (map {cfg.map.name or cfg.map.path})",
                                                    _time_iteration, cfg)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux
    return Costs(iteration_s, step_s, peak)


def _guarded(what: str, fn, *args) -> float:
    try:
        return fn(*args)
    except SigmarlError as e:
        raise SigmarlError(f"{what}: {e}") from e
    except Exception as e:  # a map or environment that cannot be built: what training would meet
        first = (str(e).strip().splitlines() or [""])[0]
        raise SigmarlError(f"{what} cannot be built: {type(e).__name__}: {first[:300]}") from e


def _time_scenario(cfg: Config, name: str) -> float:
    """CPU seconds per step of the scenario's test environment (eval.n_sims simulations) standing still."""
    import torch

    from sigmarl.env.factory import make_scenario, step_scenario
    from sigmarl.env.paper_rules import for_evaluation
    from sigmarl.maps import scenario_map_config
    from sigmarl.scenarios import scenario

    n_agents = scenario(name).n_agents
    sc = make_scenario(for_evaluation(cfg), num_envs=cfg.eval.n_sims, n_agents=n_agents, mode="test",
                       map_cfg=scenario_map_config(name), seed=cfg.eval.seed)
    still = torch.zeros(cfg.eval.n_sims, n_agents, 2)
    step_scenario(sc, still)  # warm-up
    start = _clock()
    for _ in range(TEST_STEPS):
        step_scenario(sc, still)
    return (_clock() - start) / TEST_STEPS


def _time_iteration(cfg: Config) -> float:
    """CPU seconds of one training iteration: collection and GAE timed whole, one epoch of the
    update timed and counted ppo.epochs times."""
    import torch

    from sigmarl.training.learner import Learner
    from sigmarl.training.mappo import collect, update

    learner = Learner(cfg, [cfg.seed], torch.device(cfg.device))
    try:
        start = _clock()
        data = learner.advantage(collect(learner.batches))
        collected = _clock()
        update(data, learner.loss, learner.optimiser, replace(cfg.ppo, epochs=1))
        epoch = _clock() - collected
    finally:
        learner.close()
    return collected - start + cfg.ppo.epochs * epoch


def report_lines(plan: SweepPlan, configs: dict[str, Config], costs: Costs, took: float) -> list[str]:
    """The jobs with their estimated compute, and where the figures come from."""
    lines = [f"sigmarl sweep --check: {len(plan.jobs)} job(s) in {len(plan.units)} unit(s); every map loaded, "
             f"every scenario and training set-up built; nothing trained or written ({took:.0f} s)"]
    width = max(len(j.key) for j in plan.jobs)
    lines.append(f"  {'job':<{width}}  {'train':>9}  {'evaluate':>9}")
    total = 0.0
    for job in plan.jobs:
        cfg = configs[job.label]
        train = costs.iteration_s.get(cfg.fingerprint, 0.0) * cfg.ppo.iterations
        evaluate = sum(costs.step_s[s] for s in cfg.eval.scenarios) * cfg.eval.steps
        total += train + evaluate
        lines.append(f"  {job.key:<{width}}  {_duration(train) if train else 'none':>9}  {_duration(evaluate):>9}")
    workers = _workers(plan)
    lines.append(f"in all: {_duration(total)} of compute; with {workers} worker(s) at once about "
                 f"{_duration(total / min(workers, len(plan.units)))} if each has a core of its own")
    lines.append(f"memory: about {costs.peak_mib:.0f} MiB a worker (this check's peak, having built and run one "
                 "training iteration and every scenario)")
    lines.append(f"source: CPU time measured here on {_cpu()} ({configs[plan.jobs[0].label].threads} thread(s)): "
                 f"one training iteration per training config (collection and GAE, one update epoch counted "
                 f"ppo.epochs times) and {TEST_STEPS} steps of each scenario; the policy's own evaluation "
                 "forward passes are not counted")
    return lines


def _workers(plan: SweepPlan) -> int:
    found = [h.split("=", 1)[1] for h in plan.hydra if h.split("=", 1)[0].lstrip("+~") == "hydra.launcher.n_jobs"]
    return max(1, int(found[-1])) if found and found[-1].isdigit() else 1


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 90 * 60:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def _cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    import platform

    return platform.processor() or platform.machine()
