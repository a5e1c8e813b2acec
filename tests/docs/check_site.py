"""Checks the docs site: every link of the built book, and every path into the code its pages name.

Usage: check_site.py BOOK_DIR DOCS_DIR REPO_ROOT

* BOOK_DIR: mdBook's output (target/book). Every `href` and `src` of every page of the book
  (not of the API reference under api/, which rustdoc checks) that stays on the site must
  name a file of the site (an absolute path from the site's root), and its `#fragment` an
  `id` of that page. Links leaving the site
  (a scheme such as https:, mailto:) are not followed: the tests run offline.
* DOCS_DIR: the Markdown sources. Every backticked path that starts with a top-level
  directory or file of REPO_ROOT (`crates/...`, `tests/...:LINE`) must be a file or directory
  of the repository, with at least LINE lines when a line is given.

Prints each broken link as PAGE: LINK (why) and exits 1 when there is one; 0 otherwise.
"""

import html.parser
import os
import re
import sys
import urllib.parse


class Page(html.parser.HTMLParser):
    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.ids = set()
        self.links = []

    def handle_starttag(self, tag, attrs):
        for k, v in attrs:
            if k in ("id", "name") and v:
                self.ids.add(v)
            elif k in ("href", "src") and v is not None:
                self.links.append(v)


def parse(path, cache={}):
    if path not in cache:
        p = Page()
        with open(path, encoding="utf-8") as f:
            p.feed(f.read())
        cache[path] = p
    return cache[path]


def check_book(book):
    bad = []
    pages = []
    for d, dirs, files in os.walk(book):
        rel = os.path.relpath(d, book)
        if rel == "api" or rel.startswith("api" + os.sep):
            dirs[:] = []
            continue
        pages += [os.path.join(d, f) for f in files if f.endswith(".html")]
    if not pages:
        return [f"{book}: no pages (was the book built?)"]
    for page in sorted(pages):
        for link in parse(page).links:
            u = urllib.parse.urlsplit(link)
            if u.scheme or u.netloc or link.startswith("javascript:"):
                continue
            target = page
            if u.path:
                # An absolute path is the site's root (mdBook's 404 page uses them).
                base = book if u.path.startswith("/") else os.path.dirname(page)
                target = os.path.normpath(os.path.join(base, urllib.parse.unquote(u.path).lstrip("/")))
                if os.path.isdir(target):
                    target = os.path.join(target, "index.html")
                if not os.path.isfile(target):
                    bad.append(f"{os.path.relpath(page, book)}: {link} (no such file)")
                    continue
            frag = urllib.parse.unquote(u.fragment)
            if frag and target.endswith(".html") and frag not in parse(target).ids:
                bad.append(f"{os.path.relpath(page, book)}: {link} (no id '{frag}' in {os.path.relpath(target, book)})")
    return bad


def check_code_paths(docs, root):
    tops = {e for e in os.listdir(root) if not e.startswith(".") or e == ".ci"}
    tops -= {"target"}
    bad = []
    for name in sorted(os.listdir(docs)):
        if not name.endswith(".md"):
            continue
        with open(os.path.join(docs, name), encoding="utf-8") as f:
            lines = f.read().split("\n")
        for n, line in enumerate(lines, 1):
            for m in re.finditer(r"`([^`\s]+)`", line):
                ref = m.group(1).rstrip(".,;")
                first = ref.split("/")[0].split(":")[0]
                if first not in tops or "::" in ref or any(c in ref for c in "*<>{}$…"):
                    continue
                path, line_no = ref, None
                lm = re.match(r"^(.*?):(\d+)(?:-(\d+))?$", ref)
                if lm:
                    path, line_no = lm.group(1), int(lm.group(3) or lm.group(2))
                full = os.path.join(root, path)
                if not os.path.exists(full):
                    bad.append(f"docs/{name}:{n}: `{ref}` (no such file in the repository)")
                elif line_no is not None:
                    with open(full, encoding="utf-8", errors="replace") as f:
                        count = sum(1 for _ in f)
                    if line_no > count:
                        bad.append(f"docs/{name}:{n}: `{ref}` ({path} has {count} lines)")
    return bad


def main():
    if len(sys.argv) != 4:
        sys.stderr.write(__doc__)
        return 2
    book, docs, root = sys.argv[1:]
    bad = check_book(book) + check_code_paths(docs, root)
    for b in bad:
        print(b)
    print(f"{len(bad)} broken link(s)" if bad else "every link of the site and every path into the code resolves")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
