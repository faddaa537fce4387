"""Markdown table printing shared by the benchmark scripts (they paste into the README)."""


def print_table(rows, headers=("benchmark", "time", "note")) -> None:
    """Print rows (tuples of strings) as a Markdown table, first column padded."""
    w = max(len(headers[0]), *(len(r[0]) for r in rows))
    print("| " + " | ".join([headers[0].ljust(w), *headers[1:]]) + " |")
    print(f"|{'-' * (w + 2)}|" + "---|" * (len(headers) - 1))
    for r in rows:
        print("| " + " | ".join([r[0].ljust(w), *r[1:]]) + " |")
