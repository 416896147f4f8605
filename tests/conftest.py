"""The test run's thread policy: the package's own (one thread unless ``ADAPROJ_THREADS``
says otherwise), in force before any test module loads numpy."""

from adaproj_edge.threads import apply_thread_policy

apply_thread_policy()
