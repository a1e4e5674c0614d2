-- Lab task studies (kind = "task"): participants with their stored schedules, and one row per
-- planned trial that receives the result when the trial is answered. Timestamps as in the
-- initial migration (UTC, ISO 8601 with milliseconds).

CREATE TABLE task_participants (
    id                TEXT PRIMARY KEY,          -- random, 128 bits, hex
    study             TEXT NOT NULL REFERENCES studies (slug),
    ordinal           INTEGER NOT NULL,          -- 0, 1, 2, … within the study; picks the condition order
    label             TEXT NOT NULL,             -- the experimenter's participant code (may be empty)
    token_sha256      BLOB NOT NULL UNIQUE,      -- SHA-256 of the session token; the token is not stored
    seed              INTEGER NOT NULL,          -- the schedule's seed (u64 as its i64 bit pattern)
    schedule_version  INTEGER NOT NULL,
    file_sha256       TEXT NOT NULL,
    condition_order   TEXT NOT NULL,             -- JSON array of condition names
    trials            INTEGER NOT NULL,
    answered          INTEGER NOT NULL DEFAULT 0,
    created_at        TEXT NOT NULL,
    completed_at      TEXT,
    UNIQUE (study, ordinal)
) STRICT;

CREATE TABLE task_trials (
    participant       TEXT NOT NULL REFERENCES task_participants (id),
    trial             INTEGER NOT NULL,          -- 1-based position in the schedule
    task              TEXT NOT NULL,             -- the task's name in the study file
    kind              TEXT NOT NULL CHECK (kind IN ('distance', 'placement', 'contact')),
    condition         TEXT NOT NULL CHECK (condition IN ('none', 'shadows', 'gi')),
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
    PRIMARY KEY (participant, trial)
) STRICT, WITHOUT ROWID;
