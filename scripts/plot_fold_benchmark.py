#!/usr/bin/env python3
"""Plots of fold_benchmark: reads DIR/folds.csv, DIR/summary.json and DIR/folds/NN_final.png, writes
DIR/ranking.png (each reward setting's reward of every fold against the fold's quality q, with Spearman's rho and its
bootstrap interval), DIR/perspective.png (the perspective RGB-D camera against the orthographic one), DIR/folds.png (the camera's image of each fold at the end, in order of q) and DIR/tables.md (with the strategies family, per strategy too);
from DIR/ceiling.csv (the ceiling experiment), DIR/ceiling.png (every rollout's q and the best so far, per stage of
the search) and q_max in DIR/tables.md; from DIR/learned.csv (the learned experiment), DIR/learned.png and its
Spearman's rho with intervals over the folds and over the policies. Any experiment's files may be missing.

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


def cluster_bootstrap_spearman(groups, resamples=10000, seed=1):
    """Spearman's rho over the (reward, q) pairs of all groups, with a percentile bootstrap 95 % interval that
    resamples whole groups (the folds of one learned policy are not independent of each other)."""
    rng = random.Random(seed)
    keys = sorted(groups)
    values = []
    for _ in range(resamples):
        pairs = [pair for _ in keys for pair in groups[keys[rng.randrange(len(keys))]]]
        values.append(stats.spearmanr([p[0] for p in pairs], [p[1] for p in pairs])[0])
    values = sorted(v for v in values if not math.isnan(v))
    pairs = [pair for k in keys for pair in groups[k]]
    return (stats.spearmanr([p[0] for p in pairs], [p[1] for p in pairs])[0], values[int(0.025 * (len(values) - 1))],
            values[int(0.975 * (len(values) - 1))])


def learned(directory, summary):
    """learned.png: the reward of every perturbed learned policy against its q (learned.csv), the policies as learned
    marked; tables.md: Spearman's rho over the folds (fold_benchmark's bootstrap over folds) and with the interval
    of a bootstrap over the policies, and within each policy."""
    with open(os.path.join(directory, 'learned.csv')) as f:
        rows = [r for r in csv.DictReader(f) if r['outcome'] == 'Ok']
    if not rows:
        return []
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for k, algorithm in enumerate(sorted({r['algorithm'] for r in rows})):
        mine = [r for r in rows if r['algorithm'] == algorithm]
        ax.plot([float(r['fold_quality']) for r in mine], [float(r['reward']) for r in mine], '.', color=f'C{k}',
                alpha=0.6, label=algorithm)
        learned_ones = [r for r in mine if r['perturbation'] == '0']
        ax.plot([float(r['fold_quality']) for r in learned_ones], [float(r['reward']) for r in learned_ones], 'o',
                mfc='none', color=f'C{k}', ms=8)
    ax.axvline(0.8, color='grey', ls='--', lw=1)
    ranked = {(r['signal'], r['q_at_least']): r for r in summary.get('results', [])
              if r.get('experiment') == 'learned_ranking'}
    high = ranked.get(('fold reward', 0.8))
    title = 'Learned policies perturbed (circles: as learned)'
    if high:
        title += f"\nfold reward, q >= 0.8: rho {high['spearman']:.3f} [{high['spearman_low']:.3f}, " \
                 f"{high['spearman_high']:.3f}] over {high['folds']} folds"
    ax.set_title(title, fontsize=10)
    ax.set_xlabel('fold quality q')
    ax.set_ylabel('fold reward R')
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, 'learned.png'), dpi=110)
    plt.close(fig)
    lines = ['\n### learned: the reward where learning ends\n\n',
             '| folds | policies | q range | Spearman (bootstrap over folds) | bootstrap over policies | '
             'within a policy: mean rho, policies with rho > 0 |\n', '|---|---:|---|---:|---:|---:|\n']
    for q_low in (0.0, 0.8):
        chosen = [r for r in rows if float(r['fold_quality']) >= q_low]
        groups = {}
        for r in chosen:
            groups.setdefault((r['algorithm'], r['run']), []).append((float(r['reward']), float(r['fold_quality'])))
        if len(chosen) < 3 or len(groups) < 2:
            continue
        rho, low, high_ = cluster_bootstrap_spearman(groups)
        within = [stats.spearmanr([p[0] for p in g], [p[1] for p in g])[0] for g in groups.values() if len(g) >= 3]
        within = [w for w in within if not math.isnan(w)]
        folds_row = ranked.get(('fold reward', q_low))
        by_folds = (f"{folds_row['spearman']:.3f} [{folds_row['spearman_low']:.3f}, {folds_row['spearman_high']:.3f}]"
                    if folds_row else '–')
        q = [float(r['fold_quality']) for r in chosen]
        lines.append(f"| q >= {q_low:.1f}: {len(chosen)} | {len(groups)} | {min(q):.3f}–{max(q):.3f} | {by_folds} | "
                     f"{rho:.3f} [{low:.3f}, {high_:.3f}] | "
                     f"{(sum(within) / len(within)) if within else float('nan'):.3f}, "
                     f"{sum(w > 0 for w in within)} of {len(within)} |\n")
    return lines


def main():
    directory = output_directory(__doc__)
    summary = read_summary(directory)
    lines = []
    if os.path.exists(os.path.join(directory, 'folds.csv')):
        lines += folds_tables(directory, summary)
    if os.path.exists(os.path.join(directory, 'ceiling.csv')):
        lines += ceiling(directory)
    if os.path.exists(os.path.join(directory, 'learned.csv')):
        lines += learned(directory, summary)
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
    if 'right_arc' in folds[0]:
        lines += strategies(folds)
    if 'perspective_reward' in folds[0]:
        lines += perspective(directory, folds)
    return lines


def strategies(folds):
    """tables.md lines of the strategies family: the fold reward's Spearman with q within each strategy."""
    kinds = [('one arm (the right arm 0-30 % of its arc)', lambda r: float(r['right_arc']) < 1.0),
             ('diagonal (the arcs ending inwards)', lambda r: float(r['inward']) > 0.0),
             ('late release (0.8-2 s after the movement)', lambda r: float(r['hold_after']) > 0.31)]
    lines = []
    for label, member in kinds:
        subset = [r for r in folds if member(r)]
        if len(subset) < 3:
            continue
        q = [float(r['fold_quality']) for r in subset]
        value, low, high = bootstrap_spearman([float(r['fold_reward']) for r in subset], q, resamples=2000)
        lines.append(f'| {label} | {len(subset)} | {min(q):.2f} to {max(q):.2f} | {value:.3f} | [{low:.3f}, {high:.3f}] |\n')
    if not lines:
        return []  # the scripted family: no fold of another strategy
    return ['\nThe fold reward within each strategy (bootstrap interval over its folds):\n\n'
            '| strategy | folds | q range | Spearman with q | 95 % interval |\n|---|---:|---|---:|---|\n'] + lines


def perspective(directory, folds):
    """perspective.png (the same fold through both cameras, and the two rewards of every fold) and the tables.md
    lines comparing the perspective RGB-D camera, re-projected, with the orthographic one on the same folds."""
    q = [float(r['fold_quality']) for r in folds]
    ortho = [float(r['fold_reward']) for r in folds]
    persp = [float(r['perspective_reward']) for r in folds]
    coverage = [float(r['perspective_coverage']) for r in folds]
    offset = [p - o for p, o in zip(persp, ortho)]
    n = len(offset)
    mean = sum(offset) / n
    sd = math.sqrt(sum((d - mean) ** 2 for d in offset) / (n - 1))
    half = stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n)
    paired = stats.ttest_rel(persp, ortho)
    wilcoxon = stats.wilcoxon(persp, ortho)
    rho_p = bootstrap_spearman(persp, q, resamples=2000)
    rho_o = bootstrap_spearman(ortho, q, resamples=2000)
    rho_po = bootstrap_spearman(persp, ortho, resamples=2000)
    # Whether the perspective camera ranks worse: the paired bootstrap of the difference of the two rhos.
    rng = random.Random(2)
    differences = []
    for _ in range(2000):
        idx = [rng.randrange(n) for _ in range(n)]
        differences.append(stats.spearmanr([persp[i] for i in idx], [q[i] for i in idx])[0]
                           - stats.spearmanr([ortho[i] for i in idx], [q[i] for i in idx])[0])
    differences.sort()
    low, high = differences[int(0.025 * 1999)], differences[int(0.975 * 1999)]
    fig, axes = plt.subplots(1, 4, figsize=(19, 4.2))
    best = max(range(n), key=lambda i: q[i])
    index = int(folds[best]['index'])
    for ax, (name, title) in zip(axes[:3], [('final', 'orthographic camera (the reward\'s map)'),
                                            ('rgbd', 'perspective RGB-D camera (640 x 480)'),
                                            ('rgbd_map', 'its depth re-projected into the map')]):
        path = os.path.join(directory, 'folds', f'{index:02d}_{name}.png')
        if os.path.exists(path):
            ax.imshow(Image.open(path).convert('RGB'))
        ax.set_title(f'{title}\nfold {index}, q = {q[best]:.2f}', fontsize=9)
        ax.axis('off')
    ax = axes[3]
    points = ax.scatter(ortho, persp, c=q, cmap='viridis', s=22)
    lo, hi = min(ortho + persp), max(ortho + persp)
    ax.plot([lo, hi], [lo, hi], 'k:', lw=0.8, label='equal')
    ax.set_xlabel('fold reward, orthographic camera')
    ax.set_ylabel('fold reward, perspective camera re-projected')
    ax.set_title(f'{n} folds: rho {rho_po[0]:.3f}, offset {mean:+.4f} +- {half:.4f}', fontsize=9)
    ax.legend(loc='upper left', fontsize=8)
    fig.colorbar(points, ax=ax, label='fold quality q')
    fig.tight_layout()
    fig.savefig(os.path.join(directory, 'perspective.png'), dpi=80)
    plt.close(fig)
    return [f'\nThe same {n} folds through the perspective RGB-D camera (Kinect-like: 640 x 480, f 525 px, '
            'sigma_z = 1.425e-3 z^2, 0.2 % random and edge holes), re-projected into the reward\'s map '
            '(perspective.png):\n\n| | orthographic camera | perspective camera |\n|---|---:|---:|\n',
            f'| Spearman with q (95 % bootstrap) | {rho_o[0]:.3f} [{rho_o[1]:.3f}, {rho_o[2]:.3f}] | '
            f'{rho_p[0]:.3f} [{rho_p[1]:.3f}, {rho_p[2]:.3f}] |\n',
            f'\nPerspective minus orthographic: Spearman with q {rho_p[0] - rho_o[0]:+.3f} (paired bootstrap 95 % '
            f'[{low:+.3f}, {high:+.3f}]); the two rewards rank the folds alike (Spearman {rho_po[0]:.3f} '
            f'[{rho_po[1]:.3f}, {rho_po[2]:.3f}]); reward offset {mean:+.4f} +- {half:.4f} (mean, 95 % Student-t '
            f'interval; paired t test p = {paired.pvalue:.2g}, Wilcoxon p = {wilcoxon.pvalue:.2g}); the camera saw '
            f'{100 * min(coverage):.1f}-{100 * max(coverage):.1f} % of the map.\n']


if __name__ == '__main__':
    main()
