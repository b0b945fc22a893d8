#!/usr/bin/env python3
"""Plots of fold_benchmark: reads DIR/folds.csv, DIR/summary.json and DIR/folds/NN_final.png, writes
DIR/ranking.png (each reward setting's reward of every fold against the fold's quality q, with Spearman's rho and its
bootstrap interval), DIR/folds.png (the camera's image of each fold at the end, in order of q) and DIR/tables.md.

Usage: plot_fold_benchmark.py DIR
"""
import csv
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


def main():
    directory = output_directory(__doc__)
    summary = read_summary(directory)
    rho = {r['signal']: r for r in summary['results'] if r.get('experiment') == 'ranking'}
    folds = read_folds(directory)
    if not folds:
        return
    ranking(directory, folds, rho)
    contact_sheet(directory, folds)
    with open(os.path.join(directory, 'tables.md'), 'w') as f:
        f.write(f"Spearman's rho of each reward with the fold quality q over {len(folds)} scripted folds "
                f"(seed {summary['seed']}; 95 % bootstrap interval over the folds):\n\n")
        f.write('| signal | Spearman with q | 95 % interval |\n|---|---:|---|\n')
        for r in rho.values():
            f.write(f"| {r['signal']} | {r['spearman']:.3f} | [{r['spearman_low']:.3f}, {r['spearman_high']:.3f}] |\n")
        q = [float(r['fold_quality']) for r in folds]
        f.write(f'\nq of the folds: {min(q):.3f} to {max(q):.3f}.\n')
        f.write('\nFrom (7.52) to the fold reward, one factor at a time (the same images; interval: bootstrap over the '
                'folds):\n\n| reward | Spearman with q | 95 % interval |\n|---|---:|---|\n')
        for label, signal in ABLATION:
            rho, low, high = bootstrap_spearman([signal(r) for r in folds], q, resamples=2000)
            f.write(f'| {label} | {rho:.3f} | [{low:.3f}, {high:.3f}] |\n')


if __name__ == '__main__':
    main()
