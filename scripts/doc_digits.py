"""Lists every number the guides state outside code blocks (README.md, PROTOCOL.md, docs/*.md;
docs/results.md is generated and left out) and which test, if any, fails when one of its digits
changes. It reads what each test reads rather than running the suite once per digit:

- `block`: inside a `<!-- result NAME -->` block, which tests/tests/results.rs holds to
  docs/results.md's;
- `cell` / `code` / `test`: inside the text a template of tests/tests/quoted.rs (results cells)
  or tests/tests/doc_constants.rs (the code's constants) makes, or a sentence a test holds a
  guide to with `says(FILE, ...)` (tests/tests/guides.rs; `guide_says` in the host's reader
  tests and the Python package's), in a placeholder's value;
- `literal`: inside such a text but in the template's own words: a change fails the test, but
  nothing independent computed it;
- `points`: a `cloud (N points` quote, held to the clouds block (results.rs);
- `table`: PROTOCOL.md's field tables' offsets and sizes and each frame's `(kind K, N bytes)`,
  which tests/tests/protocol_tables.rs adds up and holds to the code and the worked examples;
- `name`: not a figure: a reference (eq. 13, Table 2, issue 32, ROS 2, CRC-32, version 2, step
  6, a list's or a heading's number), a date;
- `input`: inside inline code (`-k 150`, `--bytes 2400`, `[f32; 3]`): an argument or an
  identifier a command or the code is given, not something mema says;
- `layout`: a `K = N`, `N working` or `N frozen`, held to the code's layouts (doc_device.rs);
- `left: REASON`: nothing fails, for a reason in LEFT below (a figure that is not mema's output,
  or one no test can hold);
- `-`: nothing fails, and no reason is given: what is still to be done.

A number that is part of a name (car6, f32, bun000, ouster_os1_0) is not a figure. The few
numbers that are the project's own definitions or another work's are marked by the reason in
LEFT below, so that the listing of what no test holds stays short enough to read.

Usage: python3 scripts/doc_digits.py [--all | --left]
(default: the numbers no test holds and LEFT gives no reason for; --left adds those it does)"""

import glob
import os
import re
import sys

os.chdir(os.path.join(os.path.dirname(__file__), ".."))

# A figure: digits with thousands commas, a fraction or an exponent, a ratio's `x` (88x), or
# either side of a size's `x` (1200x900); not a digit of a name (car6, f32, bun000).
NUMBER = re.compile(r"(?:(?<![\w.])|(?<=\dx))\d+(?:,\d{3})*(?:\.\d+)?(?:e-?\d+)?"
                    r"(?:x(?!\w))?(?=x\d|[^\w]|$)")
TEMPLATE_FILES = {"tests/tests/quoted.rs": "cell", "tests/tests/doc_constants.rs": "code",
                  "tests/tests/doc_device.rs": "code"}
# `K = N`, `N working`, `N frozen`: tests/tests/doc_device.rs holds each to the code's layouts.
LAYOUT = re.compile(r"(?<=K =\s)\d[\d,]*|(?<=K =\n)\d[\d,]*|\d[\d,]*(?=\s+(?:working|frozen))")
# Where tests hold a guide to a sentence (`says` in tests/tests/guides.rs, `guide_says` in the
# host's reader tests).
SOURCES = ["tests/tests", "host/src", "host/tests", "core/src", "firmware/src", "firmware-sim/src",
           "host/python/tests"]
STRINGS = r'((?:f?"(?:[^"\\]|\\.)*"\s*)+)'
PAIR = re.compile(r'\(\s*"([\w/.-]+\.md)",\s*' + STRINGS + r',?\s*\)', re.S)
SAYS = re.compile(r'says\(\s*"([\w/.-]+\.md)",\s*(?:&format!\(\s*)?' + STRINGS, re.S)


def string(literals):
    """The text of adjacent Rust or Python string literals (a Rust `\\` line continuation, a
    Python f prefix)."""
    body = "".join(m[1] for m in re.finditer(r'f?"((?:[^"\\]|\\.)*)"', literals, re.S))
    body = re.sub(r"\\\n\s*", "", body)
    return body.replace('\\"', '"').replace("\\\\", "\\")


def templates():
    for path, kind in TEMPLATE_FILES.items():
        with open(path) as f:
            for m in PAIR.finditer(f.read()):
                yield m[1], string(m[2]), kind
    sources = [glob.glob(f"{root}/**/*.{ext}", recursive=True)
               for root in SOURCES for ext in ("rs", "py")]
    for path in sorted(p for paths in sources for p in paths):
        with open(path) as f:
            for m in SAYS.finditer(f.read()):
                yield m[1], string(m[2]), "test"


def one_space(text):
    """The text with each run of white space one space, and each character's original offset."""
    out, where, space = [], [], False
    for i, c in enumerate(text):
        if c.isspace():
            space = bool(out)
            continue
        if space:
            out.append(" ")
            where.append(i)
            space = False
        out.append(c)
        where.append(i)
    return "".join(out), where


def template_spans(text, template):
    """Where the template's text is in `text`: (start, end, [placeholder spans]) in offsets of
    the original text."""
    flat, where = one_space(text)
    parts = re.split(r"(\{[^}]*\})", " ".join(template.split()))
    pattern = "".join("(.{1,48}?)" if p.startswith("{") else re.escape(p) for p in parts)
    for m in re.finditer(pattern, flat):
        holes = [(where[m.start(g)], where[m.end(g) - 1] + 1) for g in range(1, m.lastindex + 1)] \
            if m.lastindex else []
        yield where[m.start()], where[m.end() - 1] + 1, holes


def cloud_points():
    """A `cloud (N points` quote of a cloud in docs/results.md's clouds block, which
    tests/tests/results.rs holds to that block's count."""
    with open("docs/results.md") as f:
        block = re.search(r"<!-- result clouds -->(.*?)<!-- /result -->", f.read(), re.S)[1]
    names = {n for m in re.finditer(r"^\| `([^`]+)`", block, re.M)
             for n in (m[1], m[1].rsplit(".", 1)[0])}
    alternatives = "|".join(re.escape(n) for n in sorted(names, key=len, reverse=True))
    return re.compile(rf"(?:{alternatives})`? \((\d[\d,]*) points")


CLOUD_POINTS = cloud_points()


def fenced_and_blocks(text):
    """Offsets of fenced code blocks and of result blocks."""
    code = [(m.start(), m.end()) for m in re.finditer(r"^[ \t]*```.*?^[ \t]*```[^\n]*$", text, re.S | re.M)]
    blocks = [(m.start(), m.end()) for m in
              re.finditer(r"^[ \t]*<!-- result \S+ -->.*?<!-- /result -->", text, re.S | re.M)]
    return code, blocks


def protocol_tables(text):
    """Offsets of the offset and size cells of PROTOCOL.md's field tables, and of the kind and
    length in `**Frame** (kind K, N bytes)`."""
    spans = [(m.start(1), m.end(1)) for m in re.finditer(r"\*\* \((kind \d+, [\d to]+) bytes", text)]
    spans += [(m.start(1), m.end(1)) for m in re.finditer(r"\*\* \((kind \d+), no payload", text)]
    for table in re.finditer(r"^\| offset \| size \|.*\n\|[-|]*\n((?:\|.*\n)*)", text, re.M):
        for row in re.finditer(r"^\|([^|]*\|[^|]*)\|", table[1], re.M):
            spans.append((table.start(1) + row.start(1), table.start(1) + row.end(1)))
    return spans


# What makes a number a reference rather than a figure: the words before it.
REFERENCE = re.compile(
    r"(?:\b(?:eqs?|Eq|Tables?|[Ii]ssues?|ROS|REP|FIPS|Experiments?|[Ss]ections?|[Vv]ersions?|"
    r"[Ss]teps?|[Bb]enchmarks?|CPython|Python|LAS|LAZ|PCD|G|Tables \d+ and|benchmarks \d+-|"
    r"benchmarks? \d+ and)\.?[ (]?|CRC-|SHA-|^#+ )$")
DATE = re.compile(r"\b\d{4}-\d\d-\d\d\b")


def inside(at, spans):
    return any(s <= at < e for s, e in spans)


def audit(path, text, held_by):
    code, blocks = fenced_and_blocks(text)
    links = [(m.start(), m.end()) for m in re.finditer(r"\]\([^)]*\)|<!--.*?-->|https?://\S+", text)]
    points = [(m.start(1), m.end(1)) for m in re.finditer(CLOUD_POINTS, text)]
    tables = protocol_tables(text) if path == "PROTOCOL.md" else []
    layouts = [(m.start(), m.end()) for m in LAYOUT.finditer(text)]
    dates = [(m.start(), m.end()) for m in DATE.finditer(text)]
    codes = [(m.start(), m.end()) for m in re.finditer(r"`[^`\n]+`", text)]
    for m in NUMBER.finditer(text):
        at = m.start()
        hex_digits = text.startswith("0x", at) or (text[at - 2:at] == "0x" and not text[at - 3].isalnum())
        if inside(at, code) or inside(at, links) or hex_digits:
            continue
        line = text.count("\n", 0, at) + 1
        status = "-"
        before = text[text.rfind("\n", 0, at) + 1:at]
        if inside(at, blocks):
            status = "block"
        elif inside(at, dates) or REFERENCE.search(before[-40:]) or (
                re.match(r"\s*$", before) and re.match(r"\d+\. ", text[at:])):
            status = "name"
        elif inside(at, codes):
            status = "input"
        elif inside(at, points):
            status = "points"
        elif inside(at, tables):
            status = "table"
        elif inside(at, layouts):
            status = "layout"
        else:
            for kind, start, end, holes in held_by:
                if start <= at < end:
                    status = kind if inside(at, holes) else "literal"
                    break
        yield line, m[0], status


# Numbers no test holds, and why: (file pattern, pattern of the number's line, reason). The first
# that matches names the reason; a number none matches is listed as still to be done.
LEFT = [
    ("docs/testing.md", r"", "a test's parameters and bounds as testing.md describes them; the test "
     "files hold the values"),
    ("*", r"\d for a stream that ended|\bexit(s| status| with status)? \d|status \d|\(exit \d|with \d\b|exit \d|Exit status",
     "an exit status, which the behaviour tests assert (`assert_error(N, ..)`)"),
    ("docs/board.md", r"^\| \d+ \| (car6|demo|1 in|the same)",
     "one QEMU run's counts, machine-dependent, stated once with their command and machine"),
    ("docs/python.md", r"worker|machine|sharing the cores",
     "a timing, stated once with its command and machine"),
    ("docs/ros2-bags.md", r"1\.6 s", "a timing, stated once with its command and machine"),
    ("*", r"Experiment|[Tt]he issue|the paper reports|paper's Figure|Figure 12|the paper's 4 m",
     "a citation of the paper or an issue"),
    ("*", r"Crazyflie|3\.3 V|stm32f4|svd2rust|`laz` reserves|GeoKey|EPSG|2112|34735|0\.3048|"
     r"UTM northings|ECEF coordinates to|LAS 1\.|FIPS|laspy|CPython|glTF 2\.0|PCL",
     "a fact about another project, format or part"),
    ("*", r"\babout\b|~|\d to \d+ steps|a few|nearly|some \d",
     "an approximate account of measured behaviour"),
    ("*", r"\bk = \d|\bk=\d|-k \d|\d+ seeds?\b|random (points|rotations|cases)|one byte in|"
     r"-entity map|\d-thread|\d threads?\b|1 thread|ulimit|fastest of \d|\d+ Lloyd|candidate|"
     r"\d+ rounds|After \d|\d+% fewer|\d+ times farther|a Chamfer within|\d+ poses|--chunk-bytes|"
     r"query-bench|\d+ of the|its first \d|glitch|noise \d|at \d+ bytes|\d+ bytes and near",
     "a test's or a benchmark's input or bound named in prose (the test file holds it)"),
    ("*", r"\(-?1, |\(0, 0, 0\)|x_0|x_\{i|2 \+ ln k|\) / 2|\d x the|-means|[(]1 byte|\d+-point|"
     r"\d-generation|\d+ numbers|\d+ sums|\d+ integer moment|counted as 0\.5|multiples of \d+",
     "a definition or a formula's own number"),
    ("docs/board.md", r"QEMU|MHz|quiet for|every read is", "the part's and QEMU's behaviour as the board's "
     "code handles it"),
    ("PROTOCOL.md", r"", "a definition (a bit, kind or byte position, a power of two, a chosen "
     "example value)"),
    ("docs/map-format.md", r"", "a definition (a bit, byte position or code of the format)"),
    ("docs/pictures-meshes.md", r"\| .* \|", "a mesh's vertex and triangle counts as formulas"),
    ("*", r"G\(6,3\)|^and \d\. The default|[Ss]weeps? \d|scanners? \d|DE/rand/1/bin|dfu-util -a 0",
     "a name or an argument, not a figure: the paper's notation or table, a sweep's or a "
     "scanner's index, an option in inline code a line break splits"),
    ("*", r"AMD EPYC, \d cores", "the machine a measurement ran on"),
    ("*", r"^8,880 ellipsoids|fidelity issue sets|\d % the ghost is held to|the \d m threshold",
     "a citation of the paper or an issue"),
    ("*", r"GTModelType \d|glTF's \d GiB|point_step \d+|[Aa] 64 KiB device|"
     r"1\.2 mm from point to|\d+ independent vectors|returns \d+ m out",
     "a fact of a format, a part or a shared input, not of mema"),
    ("*", r"10\^9 m|\d+ km passes|one point in 10,000|at \d\s*$|all \d+ on the lower|"
     r"\d+ dropped bytes|decoder \(10\^6|under \d % of|over \d+(\.\d+)? times|"
     r"Same seed \(\d\)|\d+ stops on|nearest its first point\), \d|in 1 mm units;|optimises the whole at \d|"
     r"approximations within 10\^-\d",
     "a test's or a benchmark's input, bound or build setting named in prose (the file that runs "
     "it holds it)"),
    ("*", r"POP ≥ \d|axis is ≤ 0|\d\.\.=N|or -1|anchored at 0|around 0 in its frame|centre at 0|"
     r"^x = 0\.|\(1x\)|coded in \d+ bits|leaves at least \d$|^\(\"\d+ cm\", \"1 m\"|"
     r"a \d mm floor|\d cm patch",
     "a definition or a formula's own number"),
    ("*", r"\d+ to \d+ times slower|\d to \d % of clean|\d+ mm and more|not under \d+x|\d+ bits and more",
     "an approximate account of measured behaviour"),
    ("*", r"\b\d+-bit\b|\b2\^|\bu(8|16|32|64)\b|\bi(16|32|64)\b|f32|f64|O\(1\)|3x3|\(N, 3\)|"
     r"x, y, z|bit \d|bits \d|1e-?\d|\d+ x \d+",
     "a definition: a type's width, a power of two, a tolerance's order"),
]


def left_reason(path, line_text):
    import fnmatch
    for pattern, line, reason in LEFT:
        if fnmatch.fnmatch(path, pattern) and re.search(line, line_text):
            return reason
    return None


def main():
    show_all = "--all" in sys.argv
    show_left = "--left" in sys.argv
    reasons = {}
    by_file = {}
    for guide, template, kind in templates():
        by_file.setdefault(guide, []).append((template, kind))
    guides = ["README.md", "PROTOCOL.md"] + sorted(
        g for g in glob.glob("docs/*.md") if g != "docs/results.md")
    totals = {}
    for path in guides:
        with open(path) as f:
            text = f.read()
        held_by = [(kind, s, e, holes) for template, kind in by_file.get(path, [])
                   for s, e, holes in template_spans(text, template)]
        lines = text.splitlines()
        for line, number, status in audit(path, text, held_by):
            context = lines[line - 1].strip()
            reason = left_reason(path, context) if status == "-" else None
            if reason:
                status = "left"
                reasons[reason] = reasons.get(reason, 0) + 1
            totals[status] = totals.get(status, 0) + 1
            if show_all or status == "-" or (show_left and status == "left"):
                print(f"{path}:{line}: {number:>10}  {status:7} {context[:100]}")
    print("; ".join(f"{k} {v}" for k, v in sorted(totals.items())), file=sys.stderr)
    for reason, n in sorted(reasons.items(), key=lambda r: -r[1]):
        print(f"  left {n:4}: {reason}", file=sys.stderr)


main()
