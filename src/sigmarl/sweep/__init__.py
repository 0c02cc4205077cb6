"""`sigmarl sweep`: a study's variants x seeds as a Hydra multirun, each job training one run
and then evaluating it.

A study declares its variants (label -> overrides of the training config), a baseline and
seeds (`conf/study/<name>.yaml`). The sweep plans every job first, in this process: it
composes each job's config (a typo or bad value ends here, in one line, before anything
trains), refuses two different training configs under one label and a run folder that holds
another config's run, and writes the plan to a file. Hydra's launcher (joblib by default, any
other launcher plugin via `hydra/launcher=...`) then runs one job per plan entry, and each job
composes its config from the plan. A job that fails writes `failed.txt` into its run folder
and returns, so the others go on. Re-running the same sweep skips finished work: training
resumes from its last checkpoint or returns at once when finished, evaluation is skipped when
MLflow already holds a finished one under the same protocol.

On the command line, besides any override of the training config:
- `models=[M0,M4]` picks variants by label, `seeds=[0,1,2]` (or `seed=0,1,2`) the seeds;
- `obs=a,b` replaces the study's variants with those observation presets, labelled M0..M5
  (or custom-<hash>) from their flags, as a lone `sigmarl train` labels them;
- a sweep over any other key (`network.hidden=[64,64],[128,128]`) makes one variant per value
  and study variant, labelled `<variant>_<key>-<value>`.
"""

from sigmarl.sweep.launch import finished, launch, run_sweep, summarise
from sigmarl.sweep.plan import Job, SweepPlan, job_overrides, plan_sweep

# `sigmarl.sweep.job.run_job`, what each job runs, imports torch: it is not imported here (the
# launcher gets `sigmarl.sweep.task.run_job`, which imports it in the job), so
# that planning, and a sweep whose jobs are all finished, answer without it.
__all__ = ["Job", "SweepPlan", "finished", "job_overrides", "launch", "plan_sweep", "run_sweep", "summarise"]
