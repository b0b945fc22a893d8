#!/usr/bin/env python3
"""Checks that the one-screen summaries say what their sections measured: every number of a summary row's figure
and verdict in docs/RESULTS.md (the "Summary" and "Speed against peers" tables) must stand in the section its § link
points to (that heading down to the next heading of its level or above), and every number of a README paragraph
marked with <!-- numbers: docs/RESULTS.md#ANCHOR --> (the paragraph just above the mark) in that section of
RESULTS.md. So a figure changed in one place only fails.

What counts as a number: a decimal (0.535, 10.46, -0.316), an integer of three digits or more (1440), and a count
"k/n" or "k of n" (found in the section as either form, or as k in a table cell of its own with n in the section). Integers below 100 alone (runs, updates, chapter numbers)
are not checked. A thousands separator (10 412) is read as one number. A number may stand in the section with more
digits (0.83 against 0.8297 is not a match: it must be written the same).

Usage: check_results.py [REPO]   (default: the repository this script is in). Prints each number that its section
lacks as FILE:LINE: NUMBER not in SECTION, and exits 1 if there is any, else 0."""
import os
import re
import sys

HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*$")
LINK = re.compile(r"\[§\]\(#([^)]+)\)")
MARK = re.compile(r"<!--\s*numbers:\s*([^#\s]+)#([^\s]+)\s*-->")
INTEGER = r"(?:\d{1,3}(?:[  ]\d{3})+|\d+)"
COUNT = re.compile(rf"(?<![\d.])({INTEGER})\s*(?:/|of)\s*({INTEGER})(?![\d.])")
NUMBER = re.compile(r"(?<![\w.])[-−]?\d{1,3}(?:[  ]\d{3})+(?![\d.])|(?<![\w.])[-−]?\d*\.\d+|(?<![\w.])\d{3,}")


def slug(title):
    """GitHub's anchor of a heading: lower case, punctuation but - and _ dropped, spaces to -."""
    text = title.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text, flags=re.UNICODE)
    return text.replace(" ", "-")


def sections(lines):
    """anchor -> text of that heading's section (down to the next heading of its level or above)."""
    headings = []
    for i, line in enumerate(lines):
        m = HEADING.match(line)
        if m:
            headings.append((i, len(m.group(1)), slug(m.group(2))))
    out, seen = {}, {}
    for k, (start, level, anchor) in enumerate(headings):
        end = len(lines)
        for later, later_level, _ in headings[k + 1:]:
            if later_level <= level:
                end = later
                break
        # A repeated heading gets -1, -2, ... as on GitHub.
        n = seen.get(anchor, 0)
        seen[anchor] = n + 1
        out[anchor if n == 0 else f"{anchor}-{n}"] = "\n".join(lines[start:end])
    return out


def normalise(text):
    return text.replace("−", "-").replace("\u2009", " ").replace("\u00a0", " ")


def numbers(text):
    """The checked numbers of a cell or paragraph: decimals, integers >= 100, counts k/n (as ("count", k, n))."""
    text = normalise(re.sub(r"\(#[^)]*\)|\]\([^)]*\)", "", text))  # links' targets are not figures
    found = []
    for m in COUNT.finditer(text):
        found.append(("count", re.sub(r"\s", "", m.group(1)), re.sub(r"\s", "", m.group(2))))
    stripped = COUNT.sub(" ", text)
    for m in NUMBER.finditer(stripped):
        found.append(("number", re.sub(r"\s", "", m.group(0)).lstrip("-")))
    return found


def present(item, section):
    section = normalise(section)
    if item[0] == "count":
        _, k, n = item
        if re.search(rf"(?<![\d.]){grouped(k)}\s*(?:/|of)\s*{grouped(n)}(?![\d.])", section):
            return True
        # Or a table's: k in a cell of its own, n in the section (a column "runs" of n, say).
        cell = re.search(rf"\|\s*\**{grouped(k)}\**\s*\|", section)
        return cell is not None and re.search(rf"(?<![\d.]){grouped(n)}(?![\d.])", section) is not None
    return re.search(rf"(?<![\d.]){grouped(item[1])}(?!\d)", section) is not None


def grouped(value):
    """A pattern of `value` written the same, an integer with or without thousands separators."""
    if "." in value or len(value) < 4:
        return re.escape(value)
    head = len(value) % 3 or 3
    groups = [value[:head]] + [value[i:i + 3] for i in range(head, len(value), 3)]
    return r"[  ]?".join(groups)


def table_rows(lines, title):
    """(line number, cells) of the markdown table under the heading `title`."""
    rows, inside = [], False
    for i, line in enumerate(lines):
        m = HEADING.match(line)
        if m:
            if inside:
                break
            inside = m.group(2) == title
            continue
        if inside and line.startswith("|") and not re.match(r"^\|[-| :]+\|$", line):
            rows.append((i + 1, [c.strip() for c in line.strip().strip("|").split("|")]))
    return rows[1:]  # the header row


def check(repo):
    problems = []
    results_path = os.path.join(repo, "docs", "RESULTS.md")
    with open(results_path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    body = sections(lines)
    checked = 0
    for title in ("Summary", "Speed against peers"):
        rows = table_rows(lines, title)
        if not rows:
            problems.append(f"{results_path}: no table under '{title}'")
        for line_number, cells in rows:
            link = LINK.search(cells[-1])
            if not link:
                problems.append(f"{results_path}:{line_number}: a summary row without a § link to its section")
                continue
            anchor = link.group(1)
            if anchor not in body:
                problems.append(f"{results_path}:{line_number}: § link to #{anchor}, which no heading has")
                continue
            # Our figure and the verdict (and, in the speed table, the peer): every column but the first and the link.
            for cell in cells[1:-1]:
                for item in numbers(cell):
                    checked += 1
                    if not present(item, body[anchor]):
                        shown = "/".join(item[1:]) if item[0] == "count" else item[1]
                        problems.append(f"{results_path}:{line_number}: {shown} not in #{anchor}")
    readme = os.path.join(repo, "README.md")
    with open(readme, encoding="utf-8") as f:
        readme_lines = f.read().split("\n")
    for i, line in enumerate(readme_lines):
        m = MARK.search(line)
        if not m:
            continue
        target, anchor = m.group(1), m.group(2)
        if os.path.normpath(target) != os.path.join("docs", "RESULTS.md"):
            problems.append(f"{readme}:{i + 1}: a numbers mark must point to docs/RESULTS.md")
            continue
        if anchor not in body:
            problems.append(f"{readme}:{i + 1}: numbers mark to #{anchor}, which no heading of RESULTS.md has")
            continue
        start = i
        while start > 0 and readme_lines[start - 1].strip():
            start -= 1
        paragraph = "\n".join(readme_lines[start:i])
        if not paragraph.strip():
            problems.append(f"{readme}:{i + 1}: a numbers mark with no paragraph above it")
        for item in numbers(paragraph):
            checked += 1
            if not present(item, body[anchor]):
                shown = "/".join(item[1:]) if item[0] == "count" else item[1]
                problems.append(f"{readme}:{i + 1}: {shown} not in docs/RESULTS.md#{anchor}")
    return problems, checked


def main():
    repo = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if repo in ("-h", "--help"):
        print(__doc__)
        return 0
    problems, checked = check(repo)
    for p in problems:
        print(p)
    print(f"check_results: {checked} numbers checked, {len(problems)} not found in their sections")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
