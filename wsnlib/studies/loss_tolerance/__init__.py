"""Loss-tolerant orientation on real recordings: methods, loss profiles, fair tuning, metrics (issue 11).

The study behind notebooks 05 and 10 and its command line (``python -m
wsnlib.studies.loss_tolerance --help``).  Every recording given — BROAD trials (resampled to
paper 001's 50 Hz, :data:`BROAD_FS`) or your own recording files (:mod:`wsnlib.io.recording`,
any number of nodes, at their own rate) — is run through every method of a registry under
every loss profile, at its own rate, and scored against its reference; :mod:`.summary` turns
the tidy tables into means with bootstrap intervals, rankings and the issue's targets,
:mod:`.tables` into the notebooks' tables and sentences.

Your own recording, start to finish::

    from wsnlib.studies import loss_tolerance as study
    units = study.load_recordings(["walk.csv", "run.csv"])      # one unit per node with a reference
    print(study.units_health(units))                            # what to fix before a study
    result = study.evaluate(units, rng=np.random.default_rng(0))
    print(result.rmse_table())                                  # recording, node, method, profile, draw, RMSEs

(the command line does the same: ``python -m wsnlib.studies.loss_tolerance walk.csv run.csv``).

Fair tuning
-----------
One budget for every method, the peers' and ours: a method with something to tune is defined by
its search space (:attr:`Method.space`: each setting's physical bounds, and why — VQF's τ, Fusion's
1/gain and the Kalman filter's noise densities over its gyroscope noise are correction time
constants from 0.1 s to 100 s, Madgwick's β is √(3/4) × a gyroscope error from 0.1 to 300 °/s,
…), and its grid is :data:`DEFAULT_BUDGET` settings log-spaced from bound to bound
(:func:`space_grid`; 4 × 3 for two settings); :func:`with_budget` gives every method another
number (``--budget 1000`` on the command line).  A chosen value at a grid edge is at a physical
bound: :func:`.summary.edge_picks` flags it.  Tuning happens **once**, at the headline profile
(:data:`HEADLINE`, Gilbert–Elliott 10 %, mean burst 3 packets of 6 samples, for notebook 10;
lossless for notebook 05): every setting is scored by the trial's total RMSE over movement samples
(the mean over the headline's loss draws), and leave-one-group-out
(:func:`wsnlib.loto.leave_one_out_choice` with groups) gives each trial the setting with the
lowest mean score over the trials of the *other* groups (by default the recordings: the nodes of
one recording file are held out together; in notebook 10 BROAD's kinds of motion,
:func:`holdout_groups`).  Under every other profile, each trial is scored with the setting chosen
for it at the headline profile — so a setting is never tuned on the recording it is scored on,
and the other profiles show how a setting tuned for one loss pattern carries over.  With a single
recording there is nothing to tune on: every method runs with its documented default
(:attr:`Method.default`), and the result says so (``setting_source``).

The design, too, is chosen in the fold where it was chosen on the scored trials: the Kalman
filter's and the smoother's defaults (:class:`~wsnlib.orientation.KalmanSettings`) were picked
on BROAD's 17 trials (:data:`DESIGNED_ON_BROAD`), so the registry also runs them as
``"Kalman, design in fold"`` and ``"smoother, design in fold"``, whose grid crosses the 12
settings with :data:`KALMAN_DESIGNS` (each alternative a default was picked against, one at a
time: :attr:`Method.designs`, :func:`method_grid`).  On BROAD these stand for ours in the
headline (``exclude=DESIGNED_ON_BROAD`` of :func:`.summary.best_methods` and
:func:`.summary.targets_table`); the designed-on-all entries beside them (:data:`DESIGN_PAIRS`)
show the optimism.  Their search is the budget times the number of designs, and the notebook says so.

Loss profiles
-------------
Lossless; the paper's burst, one per run (:class:`BurstPositions`: 4 packets of 6 samples, the
run repeated with the burst at 8 places over the recording's movement, no randomness; its response
is measured against the error just before it, :func:`wsnlib.metrics.single_burst_response`);
Gilbert–Elliott 5/10/20 % with a mean burst of 3 packets of 6 samples; and GE 10 % with 1- and
12-sample packets (mean burst 3 *packets*, so the gaps scale with the packet).  Profiles are in
seconds and packets: at each recording's own rate a packet of 6 samples lasts 6 / fs seconds.
Masks are drawn from a child of the ``rng`` passed in, one per trial
(:meth:`numpy.random.Generator.spawn`), and within it one generator per profile, so a trial's
masks depend neither on how many trials nor on which other profiles run, and every method sees
the same masks (paired comparison).  ``draws`` masks per trial for each random profile (one by
default); every draw (and every burst position) is a row of the results.

The ablation and the side question
----------------------------------
The registry runs each filter with each gap handling (:data:`ABLATION`: Madgwick, Kalman,
Fusion, VQF × hold, constant rate, linear replay, AR, AR + replay), so that
:func:`.summary.ablation_table` and :func:`.summary.ratio_table` tell what the filter and what the
gap handling contribute, and the targets are stated against the best peer with the same gap
handling as ours and against the peers as users run them today (:data:`AS_USERS_RUN_THEM`).  The
*gated* hybrid (ours and Fusion's wrapped in it) applies the single frame only where
:class:`wsnlib.orientation.SingleFrameGate` trusts it; :data:`GATING_PAIRS` and
:data:`GAP_PREDICTION_PAIRS` name the pairs of :func:`.summary.paired_comparisons`.

Where it runs
-------------
Every run of a method on a trial is an independent job (:func:`wsnlib.parallel.run_jobs`):
local worker processes by default (``n_jobs``), or the workers of a Dask cluster
(``scheduler="tcp://host:8786"``, ``--scheduler`` on the command line).  Masks are drawn
before the jobs start and results are gathered in a fixed order, so the tables are the same
wherever the jobs ran.

Latency
-------
One rule: a method's latency is how long after a sample arrives its output for that sample is
final.  Causal filters output each sample when it arrives (0 s) — also gyro interpolation and
the Kalman filter's replay, which re-run a gap with the first sample *after* it but change only
the state from there on, never an output already given (the lost samples keep the estimate
given at the time).  The smoother needs the whole recording (latency = duration).

Paper 001 on real data
----------------------
:func:`paper001_methods` is the registry of notebook 05: the paper's options on Madgwick's
filter (hold, Δt extension, gyroscope interpolation, adaptive β, the hybrid), the single frame
held over gaps, and Fusion and VQF plain and wrapped in the hybrid (output and feedback), each
with one gain grid, tuned leave-one-trial-out without loss (``headline="lossless"``).

Modules
-------
:mod:`.recordings` is what the study runs on (:class:`StudyRecording`, one IMU at its own rate)
and where it comes from (:func:`load_recordings`: BROAD trial names or recording files);
:mod:`.registry` holds the methods (:func:`default_methods`, :func:`paper001_methods`, the
grids) and the loss profiles (:data:`PROFILES`); :mod:`.evaluation` runs and scores them
(:func:`evaluate`); :mod:`.summary` and :mod:`.tables` read the results; ``__main__`` is the
command line.  This package's door gathers the names of the first three.
"""

from wsnlib.studies.loss_tolerance.evaluation import (
    AFTER_GAP_S,
    RECOVERY_THRESHOLD_DEG,
    RMSE_TABLE_COLUMNS,
    SETTING_SOURCES,
    SETTINGS_PER_JOB,
    LossToleranceResult,
    evaluate,
    response_window_s,
    single_frame_trust,
)
from wsnlib.studies.loss_tolerance.recordings import (
    BROAD_FS,
    REGULAR_STEP_TOLERANCE,
    StudyRecording,
    all_broad,
    from_broad,
    from_recording,
    holdout_groups,
    load_recordings,
    notebook_sources,
    units_health,
)
from wsnlib.studies.loss_tolerance.registry import (
    ABLATION,
    AS_USERS_RUN_THEM,
    BETA_SPACE,
    DEFAULT_BUDGET,
    DEFAULT_RHO_TAU,
    DESIGN_PAIRS,
    DESIGNED_ON_BROAD,
    FUSION_DEFAULT_GAIN,
    FUSION_HYBRID_SPACE,
    FUSION_SPACE,
    GAP_HANDLING_OF,
    GAP_HANDLINGS,
    GAP_PREDICTION_PAIRS,
    GATING_PAIRS,
    HEADLINE,
    HYBRID_SPACE,
    KALMAN_DESIGNS,
    KALMAN_SPACE,
    KINDS,
    LATENCY_RULES,
    MADGWICK_BETA,
    PROFILES,
    VQF_HYBRID_SPACE,
    VQF_SPACE,
    BurstPositions,
    Choice,
    Method,
    Range,
    default_methods,
    inclination_methods,
    method_grid,
    paper001_methods,
    paper001_profiles,
    settings_grid,
    space_grid,
    study_profiles,
    with_budget,
)

__all__ = [
    "ABLATION", "AFTER_GAP_S", "AS_USERS_RUN_THEM", "BETA_SPACE", "BROAD_FS", "DEFAULT_BUDGET", "DEFAULT_RHO_TAU",
    "DESIGN_PAIRS", "DESIGNED_ON_BROAD", "KALMAN_DESIGNS", "method_grid",
    "FUSION_DEFAULT_GAIN", "FUSION_HYBRID_SPACE", "FUSION_SPACE", "GAP_HANDLING_OF", "GAP_HANDLINGS",
    "GAP_PREDICTION_PAIRS",
    "GATING_PAIRS", "HEADLINE", "HYBRID_SPACE", "KALMAN_SPACE", "KINDS", "LATENCY_RULES", "MADGWICK_BETA", "PROFILES",
    "RECOVERY_THRESHOLD_DEG", "REGULAR_STEP_TOLERANCE", "RMSE_TABLE_COLUMNS", "SETTING_SOURCES", "SETTINGS_PER_JOB",
    "VQF_HYBRID_SPACE", "VQF_SPACE", "BurstPositions", "Choice", "LossToleranceResult", "Method", "Range",
    "StudyRecording", "all_broad", "default_methods", "evaluate", "from_broad", "from_recording", "holdout_groups",
    "inclination_methods", "load_recordings", "notebook_sources", "paper001_methods", "paper001_profiles",
    "response_window_s", "settings_grid", "single_frame_trust", "space_grid", "study_profiles", "units_health",
    "with_budget",
]
