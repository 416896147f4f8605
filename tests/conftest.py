"""The test run's thread policy: the package's own (one thread unless ``ADAPROJ_THREADS``
says otherwise), in force before any test module loads numpy; and the order in which
the files are handed to the workers, the slowest first."""

import pytest

from adaproj_edge.threads import apply_thread_policy

apply_thread_policy()

# The files that take longest (each a minute or more of a worker's time on two cores,
# from `--durations`), slowest first. `./tools/test` hands whole files to the workers in
# collection order (`--dist loadfile --no-loadscope-reorder`): these start first, so no
# worker is left running one of them alone at the end while the other idles. A file not
# listed only starts later; the order never changes what a test checks.
SLOW_FIRST = (
    "tests/warp/test_quality.py",
    "tests/procam/test_accuracy.py",
    "tests/app/test_handheld_targets.py",
    "tests/geometry/test_depth_warp_detailed.py",
    "tests/procam/test_bad_captures.py",
    "tests/geometry/test_depth_warp.py",
    "tests/warp/test_temporal.py",
    "tests/warp/test_random_surfaces.py",
    "tests/app/test_handheld.py",
    "tests/geometry/test_creases.py",
    "tests/content/test_warp_with_saliency.py",
    "tests/warp/test_large_bound.py",
    "tests/warp/test_planner.py",
    "tests/commands/test_install.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Move the tests of the ``SLOW_FIRST`` files to the front, in that order (a stable
    sort: the tests of a file stay together and in their own order)."""
    rank = {path: i for i, path in enumerate(SLOW_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))
