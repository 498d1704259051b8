"""The reproduction report: finished runs against the paper's published figures, claim by claim (runs by hand)."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from synthetic_runs import write_run

from spn_torchrl.analysis import energy, paper
from spn_torchrl.analysis.collect import MAX_BYTES
from spn_torchrl.analysis.energy import sig
from spn_torchrl.analysis.reproduction import COMMAND, PAPER_R_SOURCE, build_reproduction, ppo_seeds
from spn_torchrl.analysis.runs import find_runs
from spn_torchrl.analysis.stats import one_value, p_text, sample_sd, verdict, welch
from spn_torchrl.errors import SpnError

ROOT = Path(__file__).resolve().parents[1]
CONN_FINAL = [2700.0, 2800.0, 2900.0]
WEIGHTS_FINAL = [1000.0, 1100.0, 1200.0]


def curve(final: float, generations: int = 100) -> list[float]:
    return list(np.linspace(final / 10, final, generations))


@pytest.fixture(scope="module")
def evidence(tmp_path_factory) -> Path:
    """HalfCheetah: 3 finished seeds of Connections-GA and of Weights-GA, one Connections-GA seed stopped at 20
    of 100; HumanoidStandup: Connections-GA at a deliberately shortened budget of 20 generations."""
    root = tmp_path_factory.mktemp("evidence") / "runs"
    for seed, (c, w) in enumerate(zip(CONN_FINAL, WEIGHTS_FINAL)):
        write_run(root, "halfcheetah", "HalfCheetah-v5", "conn_ga", seed, curve(c), layout="flat")
        write_run(root, "halfcheetah", "HalfCheetah-v5", "weights_ga", seed, curve(w), layout="flat")
        write_run(root, "humanoidstandup", "HumanoidStandup-v5", "conn_ga", seed, curve(1.2e5 + seed, 20))
    write_run(root, "halfcheetah", "HalfCheetah-v5", "conn_ga", 3, curve(9000.0)[:20], generations=100)
    return root


@pytest.fixture(scope="module")
def result(evidence, tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduction")
    (out / "PREFACE.md").write_text("# Reproduction\n\nA hand-written preface.\n")
    return build_reproduction([evidence], out)


def claim(result, text: str) -> dict:
    [row] = [c for c in result["claims"] if c["claim"].startswith(text)]
    return row


def test_the_preface_comes_first_verbatim(result):
    readme = Path(result["markdown"])
    assert readme.name == "README.md"
    assert readme.read_text().startswith("# Reproduction\n\nA hand-written preface.\n\n# Results against the paper")
    assert (readme.parent / "halfcheetah.png").read_bytes()[:4] == b"\x89PNG"
    assert json.loads((readme.parent / "report.json").read_text())["claims"] == result["claims"]


def test_unfinished_runs_are_not_pooled_and_listed_apart(result):
    conn = result["tasks"]["halfcheetah"]["methods"]["conn_ga"]
    assert conn["seeds"] == [0, 1, 2] and conn["rows"] == 100
    assert conn["final_return_mean"] == pytest.approx(2800.0)
    assert (conn["final_return_min"], conn["final_return_max"]) == (2700.0, 2900.0)
    md = Path(result["markdown"]).read_text()
    assert "halfcheetah conn_ga seed 3: 20 of 100 generations" in md
    assert "Not pooled (stopped before their budget): conn_ga seed 3 (20 of 100 generations)." in md


def test_welch_verdicts_against_the_published_figures(result):
    rows = {r["algo"]: r for r in result["comparisons"]["halfcheetah"]}
    published = paper.FINAL[("halfcheetah", "conn_ga")]
    expected = welch(2800.0, float(np.std(CONN_FINAL, ddof=1)), 3, published.mean, sample_sd(published.std, 10), 10)
    assert rows["conn_ga"]["p"] == pytest.approx(expected.p)
    assert rows["conn_ga"]["verdict"] == verdict(expected) and rows["conn_ga"]["verdict"].startswith("consistent")
    assert rows["weights_ga"]["verdict"].startswith("lower than the paper, p = ")
    md = Path(result["markdown"]).read_text()
    assert f"| Connections-GA | 3 | 100 | 2800 +- 82 | 2700 - 2900 | 2759 +- 772 | {rows['conn_ga']['verdict']} |" in md


def test_the_claims_table(result):
    reach = claim(result, "Connections-GA reaches the PPO level R on HalfCheetah")
    g = int(np.argmax(np.mean([curve(c) for c in CONN_FINAL], axis=0) >= paper.PPO_LEVEL["halfcheetah"])) + 1
    assert reach["status"] == "confirmed" and f"reached at generation {g}" in reach["ours"]
    assert "(paper's R)" in reach["ours"]
    assert "[3 seed(s) of the paper's 10]" in reach["ours"]
    assert (
        "[3 / 3 seed(s) of the paper's 10]" in claim(result, "Connections-GA beats Weights-GA on HalfCheetah")["ours"]
    )
    assert result["tasks"]["halfcheetah"]["ppo_level_source"] == PAPER_R_SOURCE
    assert claim(result, "Connections-GA beats Weights-GA on HalfCheetah")["status"] == "confirmed"
    assert claim(result, "Weights-GA does not reach the PPO level R on HalfCheetah")["status"] == "confirmed"
    assert claim(result, "Connections-GA reaches the PPO level R on Swimmer")["status"] == "not yet run"
    assert claim(result, "Connections-PPO does not converge on HalfCheetah")["status"] == "not yet run"
    assert claim(result, "Connections-GA reaches the upper limit 500 on CartPole-v1")["status"] == "not yet run"
    gamma = claim(result, "Table 1: Connections-GA needs at most gamma = 18.3 times PPO's data on HalfCheetah")
    assert (
        gamma["status"] == "confirmed" and f"G = {g}, E = {sig(g * 1000.0)}, gamma = {sig(g * 1e-3)}" in gamma["ours"]
    )
    # synthetic spike rate 0.1: E_DPN / E_SPN = (17*64 + 64*6) * 4.6 / (17*64*4.6 + 0.1*64*6*0.9) = 1.34
    inference = claim(result, "Table 2: SPN inference energy 1.3x lower than the DPN's on HalfCheetah")
    assert inference["status"] == "confirmed" and "= 1.34" in inference["ours"]
    standup = claim(result, "Connections-GA reaches the PPO level R on HumanoidStandup")
    assert standup["status"] == "confirmed"
    assert "deliberately shortened budget: 20 of the paper's 100 generations" in standup["ours"]
    md = Path(result["markdown"]).read_text()
    assert "| Connections-GA reaches the PPO level R on Swimmer |" in md and "**not yet run**" in md


def test_a_deliberately_shortened_budget_is_labelled(result):
    [row] = result["comparisons"]["humanoidstandup"]
    assert row["generation"] == 20 and row["verdict"].startswith("ours at generation 20 vs the paper's at 100: ")
    md = Path(result["markdown"]).read_text()
    assert "Connections-GA: (deliberately shortened budget: 20 of the paper's 100 generations)." in md


def test_a_seed_that_went_on_is_pooled_to_the_common_generation_and_is_also_its_own_row(tmp_path):
    """HumanoidStandup at 20 generations for most seeds, one seed on to the paper's 100: the pool's numbers stay
    those of generation 20 (shortened), the long seed is tested alone against the paper's generation 100."""
    runs = tmp_path / "runs"
    for seed in (0, 1, 2):
        write_run(runs, "humanoidstandup", "HumanoidStandup-v5", "conn_ga", seed, curve(1.2e5 + seed, 20))
    long = curve(1.2e5 + 3, 20) + list(np.linspace(1.3e5, 1.5e5, 80))
    write_run(runs, "humanoidstandup", "HumanoidStandup-v5", "conn_ga", 3, long)
    result = build_reproduction([runs], tmp_path / "out")
    m = result["tasks"]["humanoidstandup"]["methods"]["conn_ga"]
    assert (m["seeds"], m["rows"], m["budget"]["generations"]) == ([0, 1, 2, 3], 20, 20)
    assert m["final_return_mean"] == pytest.approx(1.2e5 + 1.5)
    [longer] = m["longer"]
    assert (longer["seeds"], longer["rows"], longer["final_return_mean"]) == ([3], 100, 1.5e5)
    pool, own = result["comparisons"]["humanoidstandup"]
    assert pool["generation"] == 20 and pool["verdict"].startswith("ours at generation 20 vs the paper's at 100: ")
    published = paper.FINAL[("humanoidstandup", "conn_ga")]
    expected = one_value(1.5e5, published.mean, sample_sd(published.std, 10), 10)
    assert own["generation"] == 100 and not own["shortened"] and own["p"] == pytest.approx(expected.p)
    assert own["verdict"] == verdict(expected) + " (one seed: t-test of a new value)"
    md = Path(result["markdown"]).read_text()
    row = (
        f"| Connections-GA: seed(s) 3 alone | 1 | 100 | 150000 | 150000 - 150000 | 150800 +- 9072 | {own['verdict']} |"
    )
    assert row in md
    assert "Connections-GA: seed(s) 3 went on to generation 100; the Connections-GA row above pools" in md
    assert "the curve and numbers are cut at the 20 every run reached (seeds [3] to 100: the dashed line)" in md


@pytest.mark.slow  # processes or a CLI in a subprocess
def test_cli_writes_the_reproduction_readme(evidence, tmp_path):
    cmd = [sys.executable, "-m", "spn_torchrl.report", str(evidence), "--reproduction", "--out", str(tmp_path)]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert f"wrote {tmp_path / 'README.md'}" in proc.stdout
    assert "halfcheetah conn_ga seed 3: 20 of 100 generations" in proc.stdout
    assert not (tmp_path / "report.md").exists() and (tmp_path / "humanoidstandup.png").exists()


def test_the_typed_in_paper_figures_agree_with_each_other_and_the_energy_model():
    for env, row in paper.TABLE1.items():
        assert row.E == pytest.approx(row.G * 3e5) and row.gamma == pytest.approx(row.E / paper.PPO_STEPS)
        assert paper.TABLE4_GA_FORWARD[env] == row.E
    v2_sizes = {"halfcheetah": (17, 6), "swimmer": (8, 2), "humanoidstandup": (376, 17)}  # Gym v2 (paper Fig. 3)
    for env, (n, m) in v2_sizes.items():
        assert energy.e_dpn(n, m) == pytest.approx(paper.TABLE2[env].dpn, rel=5e-3)
        assert paper.TABLE2[env].dpn / paper.TABLE2[env].spn == pytest.approx(paper.TABLE2[env].ratio, abs=0.05)
        e_ppo = energy.e_optim_ppo(n, m, paper.TABLE4_PPO_FORWARD, paper.TABLE4_PPO_BACKWARD)
        assert e_ppo == pytest.approx(paper.TABLE3[env].dpn, rel=5e-3)
        assert paper.TABLE3[env].dpn / paper.TABLE3[env].spn == pytest.approx(paper.TABLE3[env].ratio, abs=0.05)


def test_finished_dpn_ppo_runs_set_r_instead_of_the_papers(tmp_path):
    runs = tmp_path / "runs"
    for seed in (0, 1):
        write_run(runs, "swimmer", "Swimmer-v5", "conn_ga", seed, curve(150.0 + seed, 10))
        write_run(
            runs, "swimmer", "Swimmer-v5", "dpn_ppo", seed, [50.0, 90.0 + seed / 3], kind="ppo", total_env_steps=2000
        )
    write_run(runs, "swimmer", "Swimmer-v5", "dpn_ppo", 2, [5.0], kind="ppo", total_env_steps=2000)  # stopped
    result = build_reproduction([runs], tmp_path / "out")
    task = result["tasks"]["swimmer"]
    assert task["ppo_level"] == pytest.approx(90.0 + 1 / 6) and task["ppo_level_source"].startswith("dpn_ppo runs")
    assert task["methods"]["dpn_ppo"]["seeds"] == [0, 1]
    rows = {r["algo"]: r for r in result["comparisons"]["swimmer"]}
    assert rows["dpn_ppo"]["verdict"] == "not tested: the paper gives R without a std"
    reach = claim(result, "Connections-GA reaches the PPO level R on Swimmer")
    assert reach["status"] == "confirmed" and "R = 90.17 (dpn_ppo runs" in reach["ours"]
    md = Path(result["markdown"]).read_text()
    assert md.count("PPO level R: 90.17 (dpn_ppo runs") == 2 and "90.1667" not in md  # one R, printed one way
    assert "R = 107.52 (mean only)" in md and "swimmer dpn_ppo seed 2: 1000 of 2000 env steps" in md


def test_connections_ppo_is_judged_on_its_evals_not_the_iterations_between(tmp_path):
    """PPO evaluates every eval_interval iterations and writes NaN in between; the claim reads the evals."""
    runs = tmp_path / "runs"
    nan = float("nan")
    write_run(runs, "halfcheetah", "HalfCheetah-v5", "dpn_ppo", 0, [nan, 3000.0], kind="ppo", total_env_steps=2000)
    returns = [nan, -400.0, nan, 2000.0, nan, 1500.0]
    write_run(runs, "halfcheetah", "HalfCheetah-v5", "conn_ppo", 0, returns, kind="ppo", total_env_steps=6000)
    row = claim(build_reproduction([runs], tmp_path / "out"), "Connections-PPO does not converge on HalfCheetah")
    assert row["ours"].startswith("eval -400.0 at iteration 2, 1500 at 6 (does not decrease); R = 3000.00")
    assert row["status"] == "confirmed"


def test_each_ppo_seed_is_tabled_from_its_evals(tmp_path):
    """Where a PPO seed's evals start, peak and end, read past the NaN rows between evals."""
    runs = tmp_path / "runs"
    nan = float("nan")
    returns = [nan, 10.0, nan, 50.0, nan, 30.0, nan, 20.0, 45.0, 40.0]
    write_run(runs, "swimmer", "Swimmer-v5", "conn_ppo", 0, returns, kind="ppo", total_env_steps=10000)
    [run] = find_runs([runs])
    seed = ppo_seeds(run, tail=0.2)
    no_eval = write_run(tmp_path / "no_eval", "swimmer", "Swimmer-v5", "conn_ppo", 1, [nan], kind="ppo")
    assert ppo_seeds(find_runs([no_eval])[0]) is None
    assert (seed["first"], seed["first_steps"], seed["best"], seed["best_steps"]) == (10.0, 2000, 50.0, 4000)
    assert (seed["tail_min"], seed["tail_max"], seed["final"], seed["final_steps"]) == (40.0, 45.0, 40.0, 10000)
    result = build_reproduction([runs], tmp_path / "out")
    assert result["ppo_seeds"]["swimmer"]["conn_ppo"] == [ppo_seeds(run)]
    md = Path(result["markdown"]).read_text()
    assert "Connections-PPO, seed by seed (eval returns, at env steps):" in md
    assert "| 0 | 10.0 at 2k | 50.0 at 4k | 40.0 - 40.0 | 40.0 | 0.80 |" in md


def test_the_committed_reproduction_is_what_its_committed_runs_give(tmp_path):
    """reproduction/README.md and report.json are the report command's output over reproduction/runs, never edited
    by hand nor left behind by a run added without regenerating them; every committed run reached its budget."""
    committed = ROOT / "reproduction"
    result = build_reproduction(
        [committed / "runs"], tmp_path, preface=committed / "PREFACE.md", v2=[committed / "runs_v2"]
    )
    assert result["stopped"] == []
    for run in [*(committed / "runs").iterdir(), *(committed / "runs_v2").iterdir()]:
        assert sorted(p.name for p in run.iterdir()) == ["COMMIT", "config.yaml", "progress.csv"], run
        assert all(p.stat().st_size <= MAX_BYTES for p in run.iterdir()), run
    assert (tmp_path / "README.md").read_text() == (committed / "README.md").read_text(), f"run: {COMMAND}"
    for figure in (committed / "v2").glob("*.png"):
        assert (tmp_path / "v2" / figure.name).is_file(), figure
    assert json.loads((tmp_path / "report.json").read_text()) == json.loads((committed / "report.json").read_text())


def test_claims_and_rows_keep_seeds_0_to_9_and_more_seeds_get_an_all_seeds_row(tmp_path):
    """HalfCheetah with Connections-GA seeds 0-19 and Weights-GA seeds 0-19: seeds 0-9 put Connections-GA ahead,
    seeds 10-19 behind. The claims and the pooled rows are those of seeds 0-9; one more row per method pools all 20
    and the beats claim quotes the 20-seed comparison without being judged on it."""
    runs = tmp_path / "runs"
    conn = [3000.0 + 10 * s for s in range(10)] + [1000.0 + 10 * s for s in range(10)]
    weights = [2000.0 + 10 * s for s in range(20)]
    for seed in range(20):
        write_run(runs, "halfcheetah", "HalfCheetah-v5", "conn_ga", seed, curve(conn[seed]), layout="flat")
        write_run(runs, "halfcheetah", "HalfCheetah-v5", "weights_ga", seed, curve(weights[seed]), layout="flat")
    result = build_reproduction([runs], tmp_path / "out")
    methods = result["tasks"]["halfcheetah"]["methods"]
    assert methods["conn_ga"]["seeds"] == list(range(10)) == methods["weights_ga"]["seeds"]
    assert methods["conn_ga"]["final_return_mean"] == pytest.approx(np.mean(conn[:10]))
    every = result["all_seeds"]["halfcheetah"]
    assert every["conn_ga"]["seeds"] == list(range(20)) == every["weights_ga"]["seeds"]
    assert every["conn_ga"]["final_return_mean"] == pytest.approx(np.mean(conn))
    assert every["conn_ga"]["final_return_std"] == pytest.approx(np.std(conn))
    beats = claim(result, "Connections-GA beats Weights-GA on HalfCheetah")
    assert beats["status"] == "confirmed"  # seeds 0-9: 3045 vs 2045; all 20 seeds would give 2045 vs 2095
    assert beats["ours"].startswith("3045 vs 2045 at generations 100 / 100 (Welch: ")
    expected = welch(np.mean(conn), np.std(conn, ddof=1), 20, np.mean(weights), np.std(weights, ddof=1), 20)
    assert f"; all 20 / 20 seeds: 2045 vs 2095 (Welch: {p_text(expected.p)}), not the claim's basis" in beats["ours"]
    assert "seed(s) of the paper's 10]" not in beats["ours"]
    rows = result["comparisons"]["halfcheetah"]
    assert [(r["algo"], r["seeds"], r.get("pool")) for r in rows] == [
        ("conn_ga", 10, None),
        ("conn_ga", 20, "all 20 seeds"),
        ("weights_ga", 10, None),
        ("weights_ga", 20, "all 20 seeds"),
    ]
    md = Path(result["markdown"]).read_text()
    assert f"| Connections-GA: all 20 seeds | 20 | 100 | 2045 +- {np.std(conn):.0f} | 1000 - 3090 |" in md
    assert f"| Weights-GA | 10 | 100 | 2045 +- {np.std(weights[:10]):.0f} | 2000 - 2090 |" in md
    assert "Connections-GA, all 20 seeds: every finished seed pooled (0, 1, 2," in md
    assert "16, 17, 18, 19); the claims and the other rows keep the paper's protocol, seeds 0-9." in md
    assert json.loads((tmp_path / "out" / "report.json").read_text())["all_seeds"]["halfcheetah"]["conn_ga"]["seeds"]


def test_seeds_beyond_0_to_9_alone_make_no_paper_protocol_row(tmp_path):
    """A method with seeds 10-11 only is not in the paper-protocol pools (its claims are not yet run), and its
    all-seeds row says what it ran."""
    runs = tmp_path / "runs"
    for seed in (10, 11):
        write_run(runs, "swimmer", "Swimmer-v5", "conn_ga", seed, curve(150.0 + seed, 10))
    write_run(runs, "swimmer", "Swimmer-v5", "weights_ga", 0, curve(100.0, 10))
    result = build_reproduction([runs], tmp_path / "out")
    assert "conn_ga" not in result["tasks"]["swimmer"]["methods"]
    assert result["all_seeds"]["swimmer"]["conn_ga"]["seeds"] == [10, 11]
    assert claim(result, "Connections-GA reaches the PPO level R on Swimmer")["status"] == "not yet run"
    md = Path(result["markdown"]).read_text()
    assert (
        "| Connections-GA: all 2 seeds | 2 | 10 (shortened, deliberate) |" in md
        and "| Weights-GA | 1 | 10 (shortened" in md
    )
    write_run(runs, "cartpole", "CartPole-v1", "conn_ga", 12, curve(500.0, 10))
    md = Path(build_reproduction([runs], tmp_path / "again")["markdown"]).read_text()
    assert "Finished runs of tasks with no run of seeds 0-9, not reported: cartpole conn_ga seeds [12]." in md


def test_v2_runs_are_judged_beside_v5_in_their_own_columns_and_sections(tmp_path):
    """HalfCheetah: Connections-GA ahead of Weights-GA on v5, behind on v2 (mujoco_batch_mj210); Swimmer-v2
    (gym_v2, named swimmer_v2): Connections-GA alone. Each simulator's claims are judged on its own runs, the v2
    tasks under the paper's names."""
    v5, v2 = tmp_path / "runs", tmp_path / "runs_v2"
    for seed in range(3):
        write_run(v5, "halfcheetah", "HalfCheetah-v5", "conn_ga", seed, curve(3000.0 + seed), backend="mujoco_batch")
        write_run(v5, "halfcheetah", "HalfCheetah-v5", "weights_ga", seed, curve(2000.0 + seed))
        args = {"backend": "mujoco_batch_mj210"}
        write_run(v2, "halfcheetah", "HalfCheetah-v5", "conn_ga", seed, curve(1500.0 + seed), **args)
        write_run(v2, "halfcheetah", "HalfCheetah-v5", "weights_ga", seed, curve(2500.0 + seed), **args)
        write_run(v2, "swimmer_v2", "Swimmer-v2", "conn_ga", seed, curve(300.0 + seed), backend="gym_v2")
    result = build_reproduction([v5], tmp_path / "out", v2=[v2])
    beats = {c["claim"]: c for c in result["claims"]}
    beats_v2 = {c["claim"]: c for c in result["v2"]["claims"]}
    claim = "Connections-GA beats Weights-GA on HalfCheetah (generation 100)"
    assert beats[claim]["status"] == "confirmed" and beats_v2[claim]["status"] == "not confirmed"
    assert beats_v2[claim]["ours"].startswith("1501 vs 2501")
    assert beats_v2["Connections-GA beats Weights-GA on Swimmer (generation 100)"]["status"] == "not yet run"
    assert beats_v2["Connections-GA reaches the PPO level R on Swimmer"]["status"] == "confirmed"  # 302 > 107.52
    assert sorted(result["v2"]["tasks"]) == ["halfcheetah", "swimmer"]
    md = Path(result["markdown"]).read_text()
    assert "| claim | paper | ours, v5 | status, v5 | ours, v2 | status, v2 |" in md
    assert "## HalfCheetah on v2 dynamics (HalfCheetah-v5, n=17, m=6)" in md
    assert "## Swimmer on v2 dynamics (Swimmer-v2, n=8, m=2)" in md
    assert "env.backend=gym_v2, mujoco_batch_mj210" in md
    assert "![learning curves](v2/halfcheetah.png)" in md and (tmp_path / "out" / "v2" / "halfcheetah.png").is_file()
    assert json.loads((tmp_path / "out" / "report.json").read_text())["v2"]["claims"] == result["v2"]["claims"]
    alone = build_reproduction([v5], tmp_path / "alone")  # without --v2: the v5 table as before
    assert "ours, v2" not in Path(alone["markdown"]).read_text() and alone["v2"] is None


def test_a_run_on_the_other_simulator_is_refused_in_one_sentence(tmp_path):
    v5, v2 = tmp_path / "runs", tmp_path / "runs_v2"
    write_run(v5, "halfcheetah", "HalfCheetah-v5", "conn_ga", 0, curve(3000.0), backend="mujoco_batch_mj210")
    write_run(v2, "halfcheetah", "HalfCheetah-v5", "conn_ga", 0, curve(3000.0), backend="mujoco_batch")
    with pytest.raises(
        SpnError, match="runs on env.backend=mujoco_batch_mj210, but .* v5 runs only: pass v2 runs with --v2"
    ):
        build_reproduction([v5], tmp_path / "a")
    (v5 / "halfcheetah__conn_ga__0").rename(tmp_path / "moved")
    write_run(v5, "halfcheetah", "HalfCheetah-v5", "conn_ga", 0, curve(3000.0))
    with pytest.raises(SpnError, match="runs on env.backend=mujoco_batch, but .* v2 runs only"):
        build_reproduction([v5], tmp_path / "b", v2=[v2])
    cmd = [sys.executable, "-m", "spn_torchrl.report", str(v5), "--v2", str(v2)]
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    assert (
        done.returncode == 1
        and done.stderr.strip() == "error: --v2 goes with --reproduction (the claims table on v2 beside v5)"
    )
