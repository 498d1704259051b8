"""Per-call cost of the PPO actor and critic as the project builds them (Keyed) against TensorDictModule.

    python benchmarks/ppo_modules.py [--env halfcheetah] [--calls 500 --repeats 5]

Times one collection step's actor call (a single observation, no grad) and one minibatch's actor and critic
forward and backward (``algo.minibatch_size`` observations), each built twice from the same weights: with the
project's ``Keyed`` and with TensorDictModule in its place. TensorDictModule passes every output through
``TensorDict.from_any``, which (tensordict 0.14) searches sys.path for pandas on each call where pandas is not
installed. The last line is ``step_speedup=<x> minibatch_speedup=<y>``.
"""

from __future__ import annotations

import argparse
import importlib.util
import time
from collections.abc import Callable
from pathlib import Path

import torch
from hydra import compose, initialize_config_dir
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule

from spn_torchrl.config import register_configs, to_run_config
from spn_torchrl.envs import make_transformed_env, task_spec
from spn_torchrl.training import ppo


def per_call_ms(call: Callable[[], object], calls: int) -> float:
    call()
    start = time.perf_counter()
    for _ in range(calls):
        call()
    return (time.perf_counter() - start) / calls * 1e3


def as_tensordict_modules(module: torch.nn.Module) -> torch.nn.Module:
    """The same module tree with every Keyed replaced by a TensorDictModule around the same network."""
    for name, child in module.named_children():
        if isinstance(child, ppo.Keyed):
            setattr(module, name, TensorDictModule(child.module, in_keys=child.in_keys, out_keys=child.out_keys))
        else:
            as_tensordict_modules(child)
    return module


def timings(
    actor: torch.nn.Module, critic: torch.nn.Module, step_td: TensorDictBase, batch_td: TensorDictBase, calls: int
) -> tuple[float, float]:
    """ms per collection-step actor call, and per minibatch forward and backward of the actor and critic."""

    def step() -> None:
        with torch.no_grad():
            actor(step_td.clone())

    def minibatch() -> None:
        td = critic(actor(batch_td.clone()))
        (td[actor.log_prob_keys[0]].sum() + td[critic.out_keys[0]].sum()).backward()

    return per_call_ms(step, calls), per_call_ms(minibatch, max(1, calls // 4))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="halfcheetah", help="a conf/env name")
    parser.add_argument("--calls", type=int, default=500, help="calls per timing (a minibatch: a quarter of them)")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    register_configs()
    with initialize_config_dir(config_dir=str(Path(__file__).resolve().parents[1] / "conf"), version_base=None):
        cfg = to_run_config(compose(config_name="config", overrides=["algo=dpn_ppo", f"env={args.env}"]))
    spec = task_spec(cfg.env.id)
    env = make_transformed_env(spec.env_id, 1)
    step_td = env.reset()
    batch_td = env.rollout(cfg.algo.minibatch_size).reshape(-1).exclude("next")
    built = {}
    for label in ("Keyed", "TensorDictModule"):
        torch.manual_seed(0)
        actor, critic = ppo.make_actor(cfg, spec, env), ppo.make_critic(spec, cfg.algo.hidden)
        if label == "TensorDictModule":
            actor, critic = as_tensordict_modules(actor), as_tensordict_modules(critic)
        built[label] = actor, critic
    env.close()
    print(f"{spec.env_id}: pandas installed: {importlib.util.find_spec('pandas') is not None}")
    figures = {label: (float("inf"), float("inf")) for label in built}
    for _ in range(args.repeats):  # interleaved, best of each: robust to other load on the cores
        for label, (actor, critic) in built.items():
            now = timings(actor, critic, step_td, batch_td, args.calls)
            figures[label] = (min(figures[label][0], now[0]), min(figures[label][1], now[1]))
    for label, (step, minibatch) in figures.items():
        print(f"{label:>16}: actor step {step:.3f} ms, minibatch {minibatch:.3f} ms (best of {args.repeats})")
    ours, theirs = figures["Keyed"], figures["TensorDictModule"]
    print(f"step_speedup={theirs[0] / ours[0]:.2f} minibatch_speedup={theirs[1] / ours[1]:.2f}")


if __name__ == "__main__":
    main()
