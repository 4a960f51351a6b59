"""Many dressing jobs at once on Ray, resumable: `garment batch` (docs/batch.md).

manifest.py  the jobs: a CSV/TOML manifest or patterns x bodies, checked, with stable ids
runner.py    the driver: Ray scheduling, retries of crashed jobs, interruption
task.py      one attempt as a Ray task: the job in a child process, under the timeout
child.py     that child process: calls the job function, writes its result
folders.py   each job's output folder, renamed into place whole; the folder lock
store.py     the SQLite record of jobs and results (WAL), what --resume reads
results.py   results.csv
summary.py   summary.md / summary.html: success rates, times, failures, thumbnails
thumbnails.py  off-screen pictures of the final garments
progress.py  the live line and one line per finished job
"""
