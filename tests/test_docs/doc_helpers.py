"""What the docs' tests share: the repository's root, a page's text, the
README's drop-in config (its python block after "Single components in
your own MMDet config")."""
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
