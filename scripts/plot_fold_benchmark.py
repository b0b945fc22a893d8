#!/usr/bin/env python3
"""Plots of fold_benchmark: reads DIR/folds.csv, DIR/summary.json and DIR/folds/NN_final.png, writes
DIR/ranking.png (each reward setting's reward of every fold against the fold's quality q, with Spearman's rho and its
bootstrap interval), DIR/folds.png (the camera's image of each fold at the end, in order of q) and DIR/tables.md;
from DIR/ceiling.csv (the ceiling experiment), DIR/ceiling.png (every rollout's q and the best so far, per stage of
the search) and q_max in DIR/tables.md. Either experiment's files may be missing.

Usage: plot_fold_benchmark.py DIR
"""
import csv
import math
import os
import random

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from PIL import Image  # noqa: E402
from plot_common import output_directory, read_summary  # noqa: E402
from scipy import stats  # noqa: E402


def bootstrap_spearman(x, y, resamples=10000, seed=1):
    """Spearman's rho of x with y and its percentile bootstrap 95 % interval over the pairs."""
    rng = random.Random(seed)
    n = len(x)
    values = []
    for _ in range(resamples):
        idx = [rng.randrange(n) for _ in range(n)]
        values.append(stats.spearmanr([x[i] for i in idx], [y[i] for i in idx])[0])
    values.sort()
    return stats.spearmanr(x, y)[0], values[int(0.025 * (resamples - 1))], values[int(0.975 * (resamples - 1))]

SETTINGS = [('fold', 'fold reward (default)'), ('thesis', 'thesis reward (7.52)'), ('goal', 'goal-image reward')]
# The reward changes from (7.52) to the fold reward, one factor at a time, on each fold's images: the image term
# (7.52's colour and depth terms, the goal image's mismatch, the fold term) and the acceleration weight w_a.
ABLATION = [
    ('(7.52): colour + depth terms, w_a 0.01 (thesis)', lambda r: float(r['thesis_reward'])),
    ('colour + depth terms, w_a 0.001', lambda r: -float(r['thesis_r_color']) - float(r['thesis_r_depth'])
     - 0.001 * float(r['acceleration_cost'])),
    ('goal image mismatch, w_a 0.001', lambda r: -float(r['goal_goal_mismatch']) - 0.001 * float(r['acceleration_cost'])),
    ('fold term, w_a 0.01', lambda r: -float(r['fold_mismatch']) - 0.01 * float(r['acceleration_cost'])),
    ('fold term, w_a 0.001 (the fold reward)', lambda r: float(r['fold_reward'])),
    ('fold term alone', lambda r: -float(r['fold_mismatch'])),
]


def read_folds(directory):
    with open(os.path.join(directory, 'folds.csv')) as f:
        return [r for r in csv.DictReader(f) if r['outcome'] == 'Ok']


def ranking(directory, folds, rho):
    fig, axes = plt.subplots(1, len(SETTINGS) + 1, figsize=(4.4 * (len(SETTINGS) + 1), 4.2))
    q = [float(r['fold_quality']) for r in folds]
    signals = [(f'{name} reward', label, [float(r[f'{name}_reward']) for r in folds]) for name, label in SETTINGS]
    signals.append(('fold image term (-E/E_flat)', 'fold image term, -E / E_flat',
                    [-float(r['fold_mismatch']) for r in folds]))
    for ax, (key, label, values) in zip(axes, signals):
        ax.scatter(q, values, s=14, color='tab:blue')
        r = rho.get(key)
        title = label if r is None else f"{label}\nSpearman {r['spearman']:.2f} [{r['spearman_low']:.2f}, " \
                                         f"{r['spearman_high']:.2f}]"
        ax.set_title(title, fontsize=10)
        ax.set_xlabel('fold quality q (cloth mesh)')
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel('reward of the fold')
    fig.suptitle(f'{len(folds)} scripted folds: how each camera reward ranks them against the ground truth q '
                 '(95 % bootstrap interval over the folds)', fontsize=11)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, 'ranking.png'), dpi=90)
    plt.close(fig)


def contact_sheet(directory, folds):
    ordered = sorted(folds, key=lambda r: float(r['fold_quality']))
    columns = 8
    rows = (len(ordered) + columns - 1) // columns
    fig, axes = plt.subplots(rows, columns, figsize=(2.2 * columns, 1.9 * rows), squeeze=False)
    for ax in axes.flat:
        ax.axis('off')
    for ax, r in zip(axes.flat, ordered):
        path = os.path.join(directory, 'folds', f"{int(r['index']):02d}_final.png")
        if not os.path.exists(path):
            continue
        image = Image.open(path).convert('RGB')
        w, h = image.size
        ax.imshow(image.crop((w // 5, 0, 4 * w // 5, h)))
        ax.set_title(f"#{r['index']} q {float(r['fold_quality']):.2f}  R {float(r['fold_reward']):.2f}", fontsize=8)
    fig.suptitle('The camera at the end of each fold, in order of q (R: the fold reward)', fontsize=11)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, 'folds.png'), dpi=80)
    plt.close(fig)


def ceiling(directory):
    """ceiling.png: q of every rollout of the search and the best so far; returns the tables.md lines of q_max."""
    with open(os.path.join(directory, 'ceiling.csv')) as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return []
    q = [float(r['fold_quality']) if r['outcome'] == 'Ok' else float('nan') for r in rows]
    best, running = [], float('-inf')
    for value in q:
        running = max(running, value) if not math.isnan(value) else running
        best.append(running)
    fig, ax = plt.subplots(figsize=(7, 4))
    first = [i for i, r in enumerate(rows) if r['stage'] == '1']
    ax.plot(range(len(q)), q, '.', ms=2, alpha=0.4, label='each rollout')
    ax.plot(range(len(q)), best, '-', color='C3', label=f'best so far: q_max = {best[-1]:.3f}')
    if first:
        ax.axvline(first[0], color='grey', ls='--', lw=1)
        ax.text(first[0], 0.04, ' stage 2: the 12 goals of its best fold', color='grey',
                transform=ax.get_xaxis_transform())
        ax.text(0, 0.12, ' stage 1: reach, lift, release, duration', color='grey', transform=ax.get_xaxis_transform())
    ax.set_xlabel('rollout')
    ax.set_ylabel('fold quality q')
    ax.set_title('The ceiling: CMA-ES on q itself (the ground truth)')
    ax.grid(alpha=0.3)
    ax.legend(loc='center right')
    fig.tight_layout()
    fig.savefig(os.path.join(directory, 'ceiling.png'), dpi=100)
    plt.close(fig)
    return [f'\nq_max = {best[-1]:.3f}: the best of {len(rows)} rollouts of a search on q itself (ceiling.png).\n']


def main():
    directory = output_directory(__doc__)
    summary = read_summary(directory)
    lines = []
    if os.path.exists(os.path.join(directory, 'folds.csv')):
        lines += folds_tables(directory, summary)
    if os.path.exists(os.path.join(directory, 'ceiling.csv')):
        lines += ceiling(directory)
    with open(os.path.join(directory, 'tables.md'), 'w') as f:
        f.write(''.join(lines))


def folds_tables(directory, summary):
    """ranking.png, folds.png and the tables.md lines of the folds experiment."""
    rho = {r['signal']: r for r in summary['results'] if r.get('experiment') == 'ranking'}
    folds = read_folds(directory)
    if not folds:
        return []
    ranking(directory, folds, rho)
    contact_sheet(directory, folds)
    lines = [f"Spearman's rho of each reward with the fold quality q over {len(folds)} scripted folds "
             f"(seed {summary['seed']}; 95 % bootstrap interval over the folds):\n\n",
             '| signal | Spearman with q | 95 % interval |\n|---|---:|---|\n']
    for r in rho.values():
        lines.append(f"| {r['signal']} | {r['spearman']:.3f} | [{r['spearman_low']:.3f}, {r['spearman_high']:.3f}] |\n")
    q = [float(r['fold_quality']) for r in folds]
    lines.append(f'\nq of the folds: {min(q):.3f} to {max(q):.3f}.\n')
    lines.append('\nFrom (7.52) to the fold reward, one factor at a time (the same images; interval: bootstrap over the '
                 'folds):\n\n| reward | Spearman with q | 95 % interval |\n|---|---:|---|\n')
    for label, signal in ABLATION:
        value, low, high = bootstrap_spearman([signal(r) for r in folds], q, resamples=2000)
        lines.append(f'| {label} | {value:.3f} | [{low:.3f}, {high:.3f}] |\n')
    return lines


if __name__ == '__main__':
    main()
