"""One table for tools/build_profile.py and tools/suite_profile.py: aligned text, or Markdown."""


def table(markdown, title, header, rows):
    """Prints `title`, then `header` and `rows` as aligned columns or (markdown) a Markdown table."""
    print(f"\n{title}\n")
    if markdown:
        print("| " + " | ".join(header) + " |")
        print("|" + "---|" * len(header))
        for row in rows:
            print("| " + " | ".join(str(c) for c in row) + " |")
        return
    widths = [max(len(str(c)) for c in col) for col in zip(header, *rows)]
    for row in [header] + rows:
        print("  ".join(str(c).ljust(w) for c, w in zip(row, widths)).rstrip())
