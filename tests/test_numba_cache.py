"""numba's cache folder is keyed by every kernel file's source (models/numba_cache.py): a change to a
file a kernel calls into must not reuse a kernel compiled against the old text."""

import os
import time

import numba

from hysbench.models import numba_cache


def _tree(tmp_path, files):
    root = tmp_path / "pkg"
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return [("hysbench.x", root)]


KERNEL = "import numba\n@numba.njit(cache=True)\ndef f(x):\n    return g(x)\n"
CALLEE = "import numba\n@numba.njit(cache=True)\ndef g(x):\n    return x + 1\n"


def test_a_change_in_a_called_kernel_file_changes_the_folder(tmp_path):
    roots = _tree(tmp_path, {"a.py": KERNEL, "sub/b.py": CALLEE, "c.py": "x = 1\n"})
    before = numba_cache.source_fingerprint(roots)
    assert numba_cache.source_fingerprint(roots) == before  # deterministic
    (tmp_path / "pkg" / "sub" / "b.py").write_text(CALLEE.replace("x + 1", "x + 2"))
    assert numba_cache.source_fingerprint(roots) != before


def test_files_without_numba_do_not_change_the_folder(tmp_path):
    roots = _tree(tmp_path, {"a.py": KERNEL, "c.py": "x = 1\n"})
    before = numba_cache.source_fingerprint(roots)
    (tmp_path / "pkg" / "c.py").write_text("x = 2\n")
    assert numba_cache.source_fingerprint(roots) == before


def test_the_installed_package_uses_its_fingerprinted_folder():
    folder = numba_cache.CACHE_FOLDER
    assert folder.name == f"numba-{numba_cache.source_fingerprint()}"
    assert numba.config.CACHE_DIR == str(folder)
    assert folder.is_dir()


def test_old_folders_are_pruned_but_recent_ones_kept(tmp_path):
    now = time.time()
    for k in range(8):
        p = tmp_path / f"numba-old{k}"
        p.mkdir()
        age = 10 * 3600 + k if k < 6 else 60  # six old ones, two touched a minute ago
        os.utime(p, (now - age, now - age))
    current = tmp_path / "numba-current"
    current.mkdir()
    numba_cache._prune(current)
    left = sorted(p.name for p in tmp_path.iterdir())
    # the newest KEEP (two recent + two newest old) stay, and the current one
    assert left == sorted(["numba-current", "numba-old6", "numba-old7", "numba-old0", "numba-old1"])
