"""Training cost of the CR3BP models: wall seconds per epoch, per model and preset, on the library.

The three models of the ablation (their trainers in the model table ``amorgs.models.names.MODELS``: the GMM-prior CVAE, the vanilla
CVAE, the control LSTM) are trained for a few epochs each on the high-quality rows (m_f ≥ β = 415 kg) of the
training α of the library (default data/library), at the ``small`` and ``paper`` widths (Tables 4–5), with
the given batch size and torch thread count; the median epoch time is reported, the first epoch (warm-up)
excluded.  For the LSTM the reference recurrence (``torch.nn.LSTM`` on the repeated input sequence, what
``ControlLSTM.recurrence`` replaces) is timed too, on the same rows, in alternating rounds.  Then the cost of
a full training at the paper's epochs is projected.  Prints the table and writes it to
``docs/performance.md`` (section ``training``).
Reproduce with::

    python benchmarks/training.py                   # data/library, 2 threads, full batch, 4 timed epochs

The numbers are wall time on a shared machine: run it on an otherwise idle one.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

import pandas as pd
import torch

from amorgs.config import load_config
from amorgs.data.library import read_library, read_manifest
from amorgs.models.names import get_model
from amorgs.models.lstm import ControlLSTM
from amorgs.models.training import TrainConfig

sys.path.insert(0, str(Path(__file__).resolve().parent))
from solve import markdown, write_section  # noqa: E402  (the same table format and docs section writer)


def torch_lstm_recurrence(self: ControlLSTM, h: torch.Tensor) -> torch.Tensor:
    """The reference: ``nn.LSTM`` over the sequence [h, k/N] built out in full."""
    b, n = h.shape[0], self.config.n_steps
    seq = torch.cat([h[:, None, :].expand(b, n, h.shape[1]), self.steps[None, :, None].expand(b, n, 1)], dim=2)
    return self.lstm(seq)[0]


def seconds_per_epoch(name: str, hq: pd.DataFrame, preset: str, cfg: TrainConfig) -> float:
    times: list[float] = []
    get_model(name).train(hq, preset, cfg, lambda epoch, metrics: times.append(metrics["epoch_s"]))
    return statistics.median(times[1:])


def row(preset: str, model: str, seconds: float, epochs: int, threads: int) -> dict:
    """One table row; the projection counts CPU time as wall time × threads."""
    return {"preset": preset, "model": model, "s per epoch": f"{seconds:.3g}", "paper's epochs": epochs,
            "CPU-min at those epochs": f"{seconds * epochs * threads / 60:.3g}"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--library-dir", type=Path, default=Path("data/library"))
    ap.add_argument("--config", type=Path, default=Path("config/default.yaml"), help="for the training α and β")
    ap.add_argument("--epochs", type=int, default=5, help="epochs run per model (the first is not timed)")
    ap.add_argument("--batch-size", type=int, default=16384, help="16384: full batch, as the default run")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=3, help="alternating LSTM rounds (ours, reference)")
    ap.add_argument("--paper-epochs", type=int, nargs=2, default=(1200, 600), metavar=("CVAE", "LSTM"))
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    cfg = load_config(args.config)
    problem = cfg.problems.cr3bp
    if read_manifest(args.library_dir, "cr3bp") is None:
        sys.exit(f"{args.library_dir / 'cr3bp'}: no library manifest")
    rows = pd.concat([read_library(args.library_dir, "cr3bp", f"{a:.3f}") for a in problem.alphas.train_values()],
                     ignore_index=True)
    hq = problem.filter.select(rows)
    train_cfg = TrainConfig(epochs=args.epochs, batch_size=args.batch_size, lr=1e-3, seed=0, device="cpu",
                            progress_every=0)
    table = []
    for preset in ("small", "paper"):
        for name in ("cvae_gmm", "vanilla_cvae"):
            s = seconds_per_epoch(name, hq, preset, train_cfg)
            table.append(row(preset, name, s, args.paper_epochs[0], args.threads))
            print(table[-1], flush=True)
        # The reference recurrence, timed in alternation with ours so that machine noise hits both alike.
        ours, reference = [], []
        for _ in range(args.rounds):
            ours.append(seconds_per_epoch("lstm", hq, preset, train_cfg))
            original = ControlLSTM.recurrence
            ControlLSTM.recurrence = torch_lstm_recurrence
            try:
                reference.append(seconds_per_epoch("lstm", hq, preset, train_cfg))
            finally:
                ControlLSTM.recurrence = original
        for label, runs in (("lstm", ours), ("lstm, nn.LSTM reference", reference)):
            table.append(row(preset, label, statistics.median(runs), args.paper_epochs[1], args.threads))
            print(table[-1], flush=True)
    cmd = "python benchmarks/training.py " + " ".join(sys.argv[1:])
    text = (f"Command: `{cmd}` — {len(hq)} high-quality rows (m_f ≥ {problem.filter.min_final_mass_kg:g} kg) at "
            f"the {len(problem.alphas.train_values())} training α of the library in --library-dir, batch size "
            f"{min(args.batch_size, len(hq))}, {args.threads} torch threads, median of {args.epochs - 1} epochs "
            f"after one warm-up (LSTM comparison: median of {args.rounds} alternating rounds).\n\n" + markdown(table))
    print(text)
    write_section("training", text)


if __name__ == "__main__":
    main()
