"""Checks that tutti's ROS 2 interface files are those of the ROS 2 sources, byte for byte.

Usage: interface_sources.py TARBALL[,TARBALL...] INTERFACES

TARBALL is tests/ros2/jazzy/jazzy-src.tar.xz (tests/ros2/jazzy/SOURCES.txt names each repository and
commit it holds), and geometry2-jazzy-src.tar.xz beside it (SOURCES-geometry2.txt): several,
comma-separated, are read as one tree; INTERFACES is crates/tutti-ros2/interfaces, whose SOURCES.txt lists `PKG OWNER/REPO
COMMIT DIR` per package. For each package, the commit must be the one the tarball holds of the repository,
and INTERFACES/PKG must hold exactly the msg/*.msg, srv/*.srv and action/*.action files of DIR in the
tarball, with the same bytes; no other package may be there. Prints `same N files of M packages`, or each
difference and exits with 1.
"""

import pathlib
import sys
import tarfile


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    tarballs, root = [pathlib.Path(t) for t in sys.argv[1].split(',')], pathlib.Path(sys.argv[2])
    repos = {}
    for tarball in tarballs:
        stem = tarball.name.removesuffix('jazzy-src.tar.xz').rstrip('-')
        listing = tarball.parent / (f'SOURCES-{stem}.txt' if stem else 'SOURCES.txt')
        for line in listing.read_text().splitlines():
            if line and not line.startswith('#'):
                repo, _ref, commit = line.split()
                repos[repo] = commit
    packages = [line.split() for line in (root / 'SOURCES.txt').read_text().splitlines()
                if line and not line.startswith('#')]
    problems, count = [], 0
    # The interface files of the packages' folders, by path, from every tarball.
    folders = tuple(f'{p[3]}/' for p in packages)
    members = {}
    for tarball in tarballs:
        with tarfile.open(tarball, 'r:xz') as tar:
            for m in tar.getmembers():
                if m.isfile() and m.name.startswith(folders):
                    members[m.name] = tar.extractfile(m).read()
    for pkg, repo, commit, folder in packages:
        if repos.get(repo) != commit:
            problems.append(f'{pkg}: {repo} is at {repos.get(repo)} in the tarball, not {commit}')
        theirs = {}
        for kind in ('msg', 'srv', 'action'):
            prefix = f'{folder}/{kind}/'
            for name, m in members.items():
                rest = name[len(prefix):]
                if name.startswith(prefix) and '/' not in rest and rest.endswith(f'.{kind}'):
                    theirs[f'{kind}/{rest}'] = m
        ours = {str(p.relative_to(root / pkg)): p.read_bytes()
                for p in sorted((root / pkg).glob('*/*')) if p.is_file()}
        for rel in sorted(set(theirs) | set(ours)):
            if rel not in ours:
                problems.append(f'{pkg}: {rel} is missing')
            elif rel not in theirs:
                problems.append(f'{pkg}: {rel} is not in {folder}')
            elif ours[rel] != theirs[rel]:
                problems.append(f'{pkg}: {rel} differs from {folder}/{rel}')
            else:
                count += 1
    listed = {p[0] for p in packages}
    for extra in sorted(p.name for p in root.iterdir() if p.is_dir() and p.name not in listed):
        problems.append(f'{extra}: not listed in SOURCES.txt')
    for p in problems:
        print(p)
    if problems:
        sys.exit(1)
    print(f'same {count} files of {len(packages)} packages')


if __name__ == '__main__':
    main()
