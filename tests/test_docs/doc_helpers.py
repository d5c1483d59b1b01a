"""What the docs' tests share: the repository's root, a page's text, the
README's drop-in config (its python block after "Single components in
your own MMDet config"), the anchors of a page and its broken links."""
import os.path as osp
import re

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))


def read_text(path):
    """A page's text (UTF-8)."""
    with open(path, encoding='utf-8') as f:
        return f.read()


def readme_snippet():
    """The README's python block after "Single components in your own
    MMDet config"."""
    text = read_text(osp.join(ROOT, 'README.md'))
    start = text.index('Single components in your own MMDet config')
    return re.search(r'```python\n(.*?)```', text[start:], flags=re.S)[1]


#: ``[text](target)`` of a markdown link or image.
LINK = re.compile(r'\]\(([^)\s]+)\)')
#: A fenced code block.
FENCE = re.compile(r'^(```|~~~).*?^\1', flags=re.S | re.M)


def github_anchor(heading):
    """GitHub's anchor of a heading's text: lower case, punctuation other
    than ``-`` and ``_`` dropped, each space a ``-``."""
    text = re.sub(r'\[([^\]]*)\]\([^)]*\)', r'\1', heading.strip())
    text = re.sub(r'[^\w\- ]', '', text.lower())
    return text.replace(' ', '-')


#: An explicit anchor, ``<a name="x"></a>`` or ``<a id="x"></a>`` (GitHub
#: scrolls a link ``#x`` to it: a page keeps an old heading's anchor there).
HTML_ANCHOR = re.compile(r'<a (?:name|id)="([^"]+)"\s*>\s*</a>')


def anchors(path):
    """Every anchor of a markdown file's headings (code blocks skipped;
    a repeated heading gets ``-1``, ``-2`` ... as on GitHub) and its
    explicit ``<a name=...>`` anchors."""
    text = FENCE.sub('', read_text(path))
    seen, out = {}, set(HTML_ANCHOR.findall(text))
    for line in text.splitlines():
        match = re.match(r'#{1,6} +(.*?) *#* *$', line)
        if not match:
            continue
        anchor = github_anchor(match.group(1))
        n = seen.get(anchor, 0)
        seen[anchor] = n + 1
        out.add(anchor if n == 0 else f'{anchor}-{n}')
    return out


def broken_links(path, root=ROOT):
    """(link, why) of every relative link of ``path`` whose file is
    missing, lies outside the repository, or whose anchor names no
    heading of the markdown file it points at."""
    text = FENCE.sub('', read_text(path))
    bad = []
    for target in LINK.findall(text):
        if '://' in target or target.startswith('mailto:'):
            continue
        file_part, _, anchor = target.partition('#')
        full = osp.normpath(osp.join(osp.dirname(path), file_part)) \
            if file_part else path
        if not (full + '/').startswith(osp.normpath(root) + '/'):
            bad.append((target, 'outside the repository'))
        elif not osp.exists(full):
            bad.append((target, 'no such file'))
        elif anchor and full.endswith('.md') and \
                anchor not in anchors(full):
            bad.append((target, f'no heading with anchor #{anchor} in '
                        f'{osp.relpath(full, root)}'))
    return bad
