#!/usr/bin/env python3
"""Plots of fold_benchmark: reads DIR/folds.csv, DIR/summary.json and DIR/folds/NN_final.png, writes
DIR/ranking.png (each reward setting's reward of every fold against the fold's quality q, with Spearman's rho and its
bootstrap interval), DIR/folds.png (the camera's image of each fold at the end, in order of q) and DIR/tables.md.

Usage: plot_fold_benchmark.py DIR
"""
import csv
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from PIL import Image  # noqa: E402
from plot_common import output_directory, read_summary  # noqa: E402

SETTINGS = [('fold', 'fold reward (default)'), ('thesis', 'thesis reward (7.52)'), ('goal', 'goal-image reward')]


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


if __name__ == '__main__':
    main()
