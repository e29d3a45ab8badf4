"""The documentation's relative links resolve, and docs/ stays a product's documentation.

Every markdown link in README.md, BUILD.md, docs/*.md and lab/**/*.md that is not a URL must
name a file or folder that exists; a `#anchor` must be the GitHub slug of a heading in the target
file (lowercase, punctuation other than '-' and '_' removed, spaces to '-', a repeated heading
numbered -1, -2, ...). Links and headings inside code (fenced blocks, inline `code`) are not
links. docs/*.md together stay at most 1,800 lines (issue 73: history goes to lab/). Every Python
name the README, BUILD.md and docs/*.md write out (`ldmpc.X.Y`, `ld_mpc_jax.X.Y`,
`from ld_mpc_jax.X import a, b`) imports and resolves.
"""

import glob
import os
import pkgutil
import re
import urllib.parse


ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MAX_DOCS_LINES = 1800
# Links to records that are still being produced: (file, target) -> why; remove an entry once
# its target exists.
PENDING = {
}

_FENCE = re.compile(r'^\s*(```|~~~)')
_HEADING = re.compile(r'^ {0,3}(#{1,6})\s+(.*?)\s*#*\s*$')
_INLINE_CODE = re.compile(r'(`+).*?\1')
# [text](target) or ![alt](target); the target up to whitespace or ')' (titles are dropped).
_INLINE_LINK = re.compile(r'!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]*)>?(?:\s+"[^"]*")?\s*\)')
# [label]: target (a reference definition).
_REF_DEF = re.compile(r'^ {0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+.*)?$')


def markdown_files(root: str = ROOT) -> list:
  files = [os.path.join(root, 'README.md'), os.path.join(root, 'BUILD.md')]
  files += sorted(glob.glob(os.path.join(root, 'docs', '*.md')))
  files += sorted(glob.glob(os.path.join(root, 'lab', '**', '*.md'), recursive=True))
  return [f for f in files if os.path.isfile(f)]


def _prose_lines(text: str):
  """(line number, line) outside fenced code blocks."""
  fenced = None
  for i, line in enumerate(text.splitlines(), 1):
    m = _FENCE.match(line)
    if m:
      if fenced is None:
        fenced = m.group(1)
      elif m.group(1) == fenced:
        fenced = None
      continue
    if fenced is None:
      yield i, line


def slug(heading: str) -> str:
  """GitHub's anchor for a heading's text."""
  text = re.sub(r'!?\[([^\]]*)\]\([^)]*\)', r'\1', heading)  # A link in a heading: its text.
  text = re.sub(r'<[^>]+>', '', text).strip().lower()
  text = ''.join(c for c in text if c.isalnum() or c in ' -_')
  return text.replace(' ', '-')


def anchors(path: str) -> set:
  seen, out = {}, set()
  for _, line in _prose_lines(open(path, encoding='utf-8').read()):
    m = _HEADING.match(line)
    if not m:
      continue
    s = slug(m.group(2))
    n = seen.get(s, 0)
    seen[s] = n + 1
    out.add(s if n == 0 else f'{s}-{n}')
  return out


def links(path: str):
  """(line number, target) of every link in a markdown file, code left out."""
  for i, line in _prose_lines(open(path, encoding='utf-8').read()):
    m = _REF_DEF.match(line)
    if m:
      yield i, m.group(1)
      continue
    for m in _INLINE_LINK.finditer(_INLINE_CODE.sub('', line)):
      yield i, m.group(1)


def broken_links(root: str = ROOT) -> list:
  out, cache = [], {}
  for path in markdown_files(root):
    for line, target in links(path):
      if not target or re.match(r'^[a-z][a-z0-9+.-]*:', target, re.I):  # URL, mailto:, ...
        continue
      file_part, _, anchor = target.partition('#')
      file_part = urllib.parse.unquote(file_part)
      dest = os.path.normpath(os.path.join(os.path.dirname(path), file_part)) if file_part else path
      where = f'{os.path.relpath(path, root)}:{line}: {target}'
      if (os.path.relpath(path, root), target) in PENDING:
        continue
      if not os.path.exists(dest):
        out.append(f'{where} (no such file)')
        continue
      if anchor and dest.endswith('.md'):
        if dest not in cache:
          cache[dest] = anchors(dest)
        if urllib.parse.unquote(anchor).lower() not in cache[dest]:
          out.append(f'{where} (no heading with that anchor)')
  return out


def test_slug():
  assert slug('door-open-v3 from scratch with `:cpu_tanh`: three training seeds, one of them on a GPU') == (
      'door-open-v3-from-scratch-with-cpu_tanh-three-training-seeds-one-of-them-on-a-gpu')
  assert slug('The fallback on door-open `medium`, on fresh episodes and at K = 4') == (
      'the-fallback-on-door-open-medium-on-fresh-episodes-and-at-k--4')


def test_checker_finds_broken_links(tmp_path):
  (tmp_path / 'docs').mkdir()
  (tmp_path / 'README.md').write_text(
      '# Top\n\n## A heading\n\n[ok](docs/a.md#b-c) [self](#a-heading) [gone](docs/x.md)\n'
      '[bad anchor](docs/a.md#nope) `[in code](docs/y.md)`\n\n```\n[fenced](docs/z.md)\n```\n\n'
      '[web](https://example.com/x.md)\n[ref]: docs/a.md#b-c-1\n')
  (tmp_path / 'docs' / 'a.md').write_text('# B, c\n\n# B c\n\n```\n# not a heading\n```\n')
  found = broken_links(str(tmp_path))
  assert [f.split(': ', 1)[1] for f in found] == [
      'docs/x.md (no such file)', 'docs/a.md#nope (no heading with that anchor)']


def test_relative_links_resolve():
  broken = broken_links()
  assert not broken, 'broken links:\n' + '\n'.join(broken)


def test_docs_stay_short():
  counts = {os.path.basename(p): sum(1 for _ in open(p, encoding='utf-8'))
            for p in glob.glob(os.path.join(ROOT, 'docs', '*.md'))}
  total = sum(counts.values())
  assert total <= MAX_DOCS_LINES, (
      f'docs/*.md hold {total} lines (at most {MAX_DOCS_LINES}; history belongs in lab/): '
      + ', '.join(f'{k} {v}' for k, v in sorted(counts.items(), key=lambda kv: -kv[1])))


# `ldmpc.a.b` (the README's alias) or `ld_mpc_jax.a.b`; `from ld_mpc_jax.a import b, c`.
_NAME = re.compile(r'\b(?:ldmpc|ld_mpc_jax)((?:\.[A-Za-z_]\w*)+)')
_FROM = re.compile(r'from (ld_mpc_jax(?:\.\w+)*) import ([\w, ]+)')


def python_names(text: str) -> set:
  """The dotted names under ld_mpc_jax that a markdown text writes out."""
  names = {'ld_mpc_jax' + m.group(1) for m in _NAME.finditer(text)}
  for m in _FROM.finditer(text):
    names |= {f'{m.group(1)}.{x.strip()}' for x in m.group(2).split(',') if x.strip()}
  return names


def resolves(name: str) -> bool:
  """Whether `name` imports: its longest module prefix, then the rest as attributes."""
  try:
    pkgutil.resolve_name(name)
  except (ImportError, AttributeError):
    return False
  return True


def test_the_name_checker_tells_real_names_from_gone_ones():
  text = ('`ldmpc.make_plan(config)`, ld_mpc_jax.plan.search.CANDIDATES.names(), '
          'ldmpc.search.CANDIDATES\nfrom ld_mpc_jax import checkpointing, encode\n')
  names = python_names(text)
  assert names == {'ld_mpc_jax.make_plan', 'ld_mpc_jax.plan.search.CANDIDATES.names',
                   'ld_mpc_jax.search.CANDIDATES', 'ld_mpc_jax.checkpointing', 'ld_mpc_jax.encode'}
  assert sorted(n for n in names if not resolves(n)) == [
      'ld_mpc_jax.checkpointing', 'ld_mpc_jax.search.CANDIDATES']


def test_the_python_names_in_the_docs_resolve():
  paths = ['README.md', 'BUILD.md'] + sorted(
      os.path.relpath(p, ROOT) for p in glob.glob(os.path.join(ROOT, 'docs', '*.md')))
  gone = [f'{path}: {name}' for path in paths
          for name in sorted(python_names(open(os.path.join(ROOT, path), encoding='utf-8').read()))
          if not resolves(name)]
  assert not gone, 'names the docs use that do not resolve:\n' + '\n'.join(gone)
