"""Many sessions at once (``gaitnet batch``; docs/batch.md): find the sessions under the given
folders, run ``gaitnet infer``'s own code on each on local worker processes or on a Ray
cluster, resume where a run stopped, and gather a cohort table.

Modules, from the bottom up (none is imported here: import what you use):
:mod:`~gaitnet.batch.sessions` (finding and naming sessions), :mod:`~gaitnet.batch.task` (one
session, as a worker runs it), :mod:`~gaitnet.batch.local` and :mod:`~gaitnet.batch.ray_runner`
(the two ways to run them), :mod:`~gaitnet.batch.cohort` and :mod:`~gaitnet.batch.cohort_html`
(the tables and the page), :mod:`~gaitnet.batch.run` (a batch from start to end). ``ray`` is
imported only when a batch runs on Ray.
"""
