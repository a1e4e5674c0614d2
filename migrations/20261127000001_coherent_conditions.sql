-- Coherent conditions in the lab (issue 18): a task study's condition may name one of Rohmer et
-- al.'s coherent methods — em, dit or vct, at quality med or with -low, -med or -high — beside
-- differential instant radiosity's none, shadows and gi. The CHECK on `condition` of
-- `task_trials` and `task_frame_times` allowed only the last three; sqlite cannot alter a CHECK,
-- so both tables are rebuilt with the wider one and every row copied (nothing references them).

CREATE TABLE task_trials_rebuilt (
    participant       TEXT NOT NULL REFERENCES task_participants (id),
    trial             INTEGER NOT NULL,          -- 1-based position in the schedule
    task              TEXT NOT NULL,             -- the task's name in the study file
    kind              TEXT NOT NULL CHECK (kind IN ('distance', 'placement', 'contact')),
    condition         TEXT NOT NULL CHECK (condition IN ('none', 'shadows', 'gi',
                          'em', 'em-low', 'em-med', 'em-high', 'dit', 'dit-low', 'dit-med', 'dit-high',
                          'vct', 'vct-low', 'vct-med', 'vct-high')),
    practice          INTEGER NOT NULL CHECK (practice IN (0, 1)),
    start_x REAL NOT NULL, start_y REAL NOT NULL, start_z REAL NOT NULL,    -- virtual cube centre at the start, m
    target_x REAL NOT NULL, target_y REAL NOT NULL, target_z REAL NOT NULL, -- where it should end, m
    -- The result; all NULL until the trial is answered (then all set, in one transaction).
    answer_cm         REAL,                      -- distance: the typed distance; else NULL
    final_x REAL, final_y REAL, final_z REAL,   -- placement, contact: the confirmed position, m
    error_cm          REAL,                      -- total: |answer − true distance| or |final − target|
    signed_error_cm   REAL,                      -- distance: answer − true; contact: height above the table; placement: NULL
    error_x_cm REAL, error_y_cm REAL, error_z_cm REAL,                     -- per axis, signed
    completion_ms     REAL,                      -- first frame of the trial sent → answer received
    key_log           TEXT,                      -- JSON array of {key, t_ms, client_t_ms, x, y, z}
    frames            INTEGER,                   -- frames sent during the trial
    frame_ms_mean REAL, frame_ms_max REAL,       -- renderer time per frame (render + encode)
    latency_ms_mean REAL, latency_ms_p95 REAL,   -- input received → frame showing it sent
    smoothing         INTEGER CHECK (smoothing IN (0, 1)),  -- temporal smoothing on for this trial
    adapter           TEXT,
    started_at        TEXT,
    answered_at       TEXT,
    frames_shown      INTEGER,                   -- lab hygiene (20261123000002)
    shown_at          TEXT,
    shown_frame_ms_mean REAL,
    paced_ms          REAL,
    PRIMARY KEY (participant, trial)
) STRICT, WITHOUT ROWID;
INSERT INTO task_trials_rebuilt (
    participant, trial, task, kind, condition, practice, start_x, start_y, start_z,
    target_x, target_y, target_z, answer_cm, final_x, final_y, final_z, error_cm,
    signed_error_cm, error_x_cm, error_y_cm, error_z_cm, completion_ms, key_log, frames,
    frame_ms_mean, frame_ms_max, latency_ms_mean, latency_ms_p95, smoothing, adapter,
    started_at, answered_at, frames_shown, shown_at, shown_frame_ms_mean, paced_ms)
SELECT
    participant, trial, task, kind, condition, practice, start_x, start_y, start_z,
    target_x, target_y, target_z, answer_cm, final_x, final_y, final_z, error_cm,
    signed_error_cm, error_x_cm, error_y_cm, error_z_cm, completion_ms, key_log, frames,
    frame_ms_mean, frame_ms_max, latency_ms_mean, latency_ms_p95, smoothing, adapter,
    started_at, answered_at, frames_shown, shown_at, shown_frame_ms_mean, paced_ms
FROM task_trials;
DROP TABLE task_trials;
ALTER TABLE task_trials_rebuilt RENAME TO task_trials;

CREATE TABLE task_frame_times_rebuilt (
    study             TEXT NOT NULL REFERENCES studies (slug),
    measured_at       TEXT NOT NULL,
    adapter           TEXT NOT NULL,
    condition         TEXT NOT NULL CHECK (condition IN ('none', 'shadows', 'gi',
                          'em', 'em-low', 'em-med', 'em-high', 'dit', 'dit-low', 'dit-med', 'dit-high',
                          'vct', 'vct-low', 'vct-med', 'vct-high')),
    width             INTEGER NOT NULL,
    height            INTEGER NOT NULL,
    frames            INTEGER NOT NULL,
    median_ms         REAL NOT NULL,           -- render + encode
    PRIMARY KEY (study, measured_at, condition)
) STRICT;
INSERT INTO task_frame_times_rebuilt (study, measured_at, adapter, condition, width, height, frames, median_ms)
SELECT study, measured_at, adapter, condition, width, height, frames, median_ms FROM task_frame_times;
DROP TABLE task_frame_times;
ALTER TABLE task_frame_times_rebuilt RENAME TO task_frame_times;
