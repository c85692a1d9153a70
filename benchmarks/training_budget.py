"""Bounded training (issue 40 §3): what a capped, seeded per-α sample and early stopping save, and what they cost
in model quality — paired, the same data and seeds, one process.

CR3BP: each of the paper's three models (their trainers in the model table, ``amorgs.models.names.MODELS``) is trained twice on the
high-quality rows (m_f ≥ β) of the training α of ``--config`` read from the library: ``full`` (every row, every
epoch of the config: the typed defaults) and ``bounded`` (at most ``--cap`` rows per α, ``--validation`` held out,
``--patience``). Quality: the model's own loss (negative ELBO per row for the CVAEs, the control MSE for the
LSTM; noise from a fixed seed) on the high-quality rows of the config's *test* α, which neither variant saw.

De Jong (``--dejong-hq``, the workflow's ``results/dejong/high_quality.parquet``): the GMM-prior CVAE trained
full (the typed defaults' epochs) and on a seeded sample of ≤ ``--dejong-caps`` minima per training α (optionally
with early stopping, ``--dejong-patience``); quality: the hit rate within the radius and the
minima found at each test α (``amorgs.analysis.dejong_eval.prediction_metrics``, 1000 samples, the same seed).

Prints the tables and writes them to ``docs/performance.md`` (sections ``training-budget-cr3bp``, ``-dejong``)::

    python benchmarks/training_budget.py --dejong-hq /tmp/wd/results/dejong/high_quality.parquet

CPU seconds are this process's (``time.process_time``), torch on ``--threads`` threads.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from amorgs.alphas import cap_per_alpha, rows_at_any
from amorgs.config import load_config
from amorgs.data.library import read_library
from amorgs.models import cr3bp_models as cm
from amorgs.models.names import get_model
from amorgs.models.lstm import cartesian_controls
from amorgs.models.training import TrainConfig, _validation_loss

sys.path.insert(0, str(Path(__file__).resolve().parent))
from solve import markdown, write_section  # noqa: E402


def model_data(name: str, hq: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """(x, cond) of ``name``'s loss on the rows ``hq`` — the layout its trainer uses."""
    alpha = hq["alpha"].to_numpy(float)
    if name == "cvae_gmm":
        return cm.time_mass(hq), alpha
    if name == "vanilla_cvae":
        return cm.vanilla_vectors(cm.stored_vectors(hq)), alpha
    return (cartesian_controls(cm.stored_vectors(hq), cm.N_SEGMENTS),
            cm.lstm_conditioning(cm.time_mass(hq), alpha))


def test_loss(model, name: str, hq: pd.DataFrame) -> float:
    x, cond = model_data(name, hq)
    cond = torch.as_tensor(cond, dtype=torch.float32)
    return _validation_loss(model, torch.as_tensor(x, dtype=torch.float32),
                            cond[:, None] if cond.ndim == 1 else cond, TrainConfig(batch_size=16384, seed=0))


def trained(train, *args) -> tuple[object, float, int]:
    """(model, CPU s, epochs run) of one training."""
    epochs: list[int] = []
    cpu0 = time.process_time()
    model = train(*args, on_epoch=lambda e, m: epochs.append(e))
    return model, time.process_time() - cpu0, len(epochs)


def cr3bp_rows(args, cfg) -> list[dict]:
    problem, m = cfg.problems.cr3bp, cfg.cr3bp_models
    read = lambda alphas: problem.filter.select(pd.concat(
        [read_library(args.library_dir, "cr3bp", f"{a:.3f}") for a in alphas], ignore_index=True))
    hq, truth = read(problem.alphas.train_values()), read(problem.alphas.test)
    rows = []
    for name in args.models:
        for variant in ("full", "bounded"):
            bounded = variant == "bounded"
            data = cap_per_alpha(hq, args.cap, m.seed) if bounded else hq
            tc = TrainConfig(epochs=m.epochs, batch_size=m.batch_size, lr=m.learning_rate, seed=m.seed, device="cpu",
                             progress_every=0, validation_fraction=args.validation if bounded else 0.0,
                             patience=args.patience if bounded else 0)
            model, cpu_s, ran = trained(get_model(name).train, data, m.preset, tc)
            rows.append({"problem": "cr3bp", "model": name, "variant": variant, "rows": len(data), "epochs run": ran,
                         "CPU s": round(cpu_s, 1), "test-α loss": f"{test_loss(model, name, truth):.5g}"})
            print(rows[-1], flush=True)
    return rows


def dejong_rows(args, cfg) -> list[dict]:
    from amorgs.analysis.dejong_eval import prediction_metrics
    from amorgs.models import cvae
    from amorgs.models.training import train
    from amorgs.problems import get_problem
    from amorgs.steps.dejong import _cvae_config

    c, problem = cfg.dejong_cvae, cfg.problems.dejong
    names = list(get_problem("dejong").variable_names)
    df = pd.read_parquet(args.dejong_hq)
    df = rows_at_any(df, problem.alphas.train_values()).reset_index(drop=True)
    rows = []
    # full: every minimum, every epoch; then each --dejong-caps value: ≤ cap minima per training α (seeded, as
    # dejong_cvae.max_rows_per_alpha), every epoch unless --dejong-patience
    for cap in [None, *args.dejong_caps]:
        variant = "full" if cap is None else f"≤ {cap} per α"
        sample = cap_per_alpha(df, cap, c.seed)
        x, alpha = sample[names].to_numpy(float), sample["alpha"].to_numpy(float)
        patience = args.dejong_patience if cap is not None else 0
        tc = TrainConfig(epochs=c.epochs, batch_size=c.batch_size, lr=c.learning_rate, seed=c.seed, device="cpu",
                         progress_every=0, validation_fraction=args.validation if patience else 0.0,
                         patience=patience)
        torch.manual_seed(c.seed)
        model = cvae.GMMPriorCVAE(_cvae_config(c.preset), cvae.Normalizer.from_data(x))
        model, cpu_s, ran = trained(lambda on_epoch: (train(model, x, alpha, tc, on_epoch), model)[1])
        model.eval()
        generator = torch.Generator().manual_seed(c.seed)
        scores = [prediction_metrics(model.sample(a, c.n_samples, generator=generator).detach().numpy(), a,
                                     radius=c.radius) for a in problem.alphas.test]
        hit = [s["fraction_within_radius"] for s in scores]
        found = [s["minima_covered"] for s in scores]
        rows.append({"problem": "dejong", "model": "cvae_gmm", "variant": variant, "rows": len(x), "epochs run": ran,
                     "CPU s": round(cpu_s, 1),
                     "test-α quality": " / ".join(f"{h:.3f}" for h in hit) + " hit; minima " + " / ".join(map(str, found))})
        print(rows[-1], flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--library-dir", type=Path, default=Path("data/library"))
    ap.add_argument("--config", type=Path, default=Path("config/default.yaml"),
                    help="training and test α, β, seeds and epochs (the bounded variant's cap, share and patience "
                         "come from the options)")
    ap.add_argument("--models", nargs="+", default=["cvae_gmm", "vanilla_cvae", "lstm"])
    ap.add_argument("--cap", type=int, default=600, help="rows per training α of the bounded variant")
    ap.add_argument("--validation", type=float, default=0.1)
    ap.add_argument("--patience", type=int, default=30)
    ap.add_argument("--dejong-hq", type=Path, default=None, help="a workflow's results/dejong/high_quality.parquet")
    ap.add_argument("--dejong-caps", type=int, nargs="*", default=[40],
                    help="De Jong: minima per training α of each capped variant")
    ap.add_argument("--dejong-patience", type=int, default=0, help="De Jong: early stopping of the capped "
                                                                      "variants (0: every epoch)")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--skip-cr3bp", action="store_true")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    cfg = load_config(args.config)
    cmd = "python benchmarks/training_budget.py " + " ".join(sys.argv[1:])
    setup = (f"full: every high-quality row and every epoch of the config; bounded: ≤ {args.cap} rows per training "
             f"α (seeded), {args.validation:.0%} held out, patience {{}}; {args.threads} torch thread(s).")
    if not args.skip_cr3bp:
        text = (f"Command: `{cmd}` — {setup.format(args.patience)} Quality: the model's loss on the high-quality "
                f"rows of the test α, which neither variant saw (lower is better).\n\n" + markdown(cr3bp_rows(args, cfg)))
        print(text)
        write_section("training-budget-cr3bp", text)
    if args.dejong_hq is not None:
        text = (f"Command: `{cmd}` — full: every minimum and every epoch of the config; capped: a seeded sample of "
                f"≤ cap minima per training α, patience {args.dejong_patience or 'none'}; {args.threads} torch "
                f"thread(s). Quality: the fraction of 1000 samples "
                f"within the radius of a true minimum, and the minima covered (of 8), per test α.\n\n"
                + markdown(dejong_rows(args, cfg)))
        print(text)
        write_section("training-budget-dejong", text)

if __name__ == "__main__":
    main()
