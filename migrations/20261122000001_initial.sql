-- The web survey's storage: studies, participants with their stored schedules, responses.
-- Timestamps are UTC, ISO 8601 with milliseconds ('2026-11-22T06:52:01.123Z'), set by sqlite.

CREATE TABLE studies (
    slug              TEXT PRIMARY KEY,
    title             TEXT NOT NULL,
    kind              TEXT NOT NULL,
    open              INTEGER NOT NULL CHECK (open IN (0, 1)),
    -- The checked study definition as JSON (for export and the admin pages) and the SHA-256
    -- of the study file it came from, as of the last start-up.
    definition        TEXT NOT NULL,
    file_sha256       TEXT NOT NULL,
    first_loaded_at   TEXT NOT NULL,
    loaded_at         TEXT NOT NULL
) STRICT;

CREATE TABLE participants (
    id                TEXT PRIMARY KEY,          -- random, 128 bits, hex
    study             TEXT NOT NULL REFERENCES studies (slug),
    ordinal           INTEGER NOT NULL,          -- 0, 1, 2, … within the study
    token_sha256      BLOB NOT NULL UNIQUE,      -- SHA-256 of the bearer token; the token is not stored
    seed              INTEGER NOT NULL,          -- the schedule's seed (u64 stored as its i64 bit pattern)
    schedule_version  INTEGER NOT NULL,
    file_sha256       TEXT NOT NULL,             -- the study file the schedule was made from
    demographics      TEXT NOT NULL,             -- JSON object
    client            TEXT NOT NULL,             -- JSON object: viewport, devicePixelRatio, userAgent, …
    url_params        TEXT NOT NULL,             -- JSON object: kept crowdsourcing parameters
    trials            INTEGER NOT NULL,
    answered          INTEGER NOT NULL DEFAULT 0,
    completion_code   TEXT NOT NULL,
    created_at        TEXT NOT NULL,
    completed_at      TEXT,
    UNIQUE (study, ordinal)
) STRICT;

CREATE TABLE trials (
    participant       TEXT NOT NULL REFERENCES participants (id),
    trial             INTEGER NOT NULL,          -- 1-based position in the participant's schedule
    left_condition    TEXT NOT NULL,
    right_condition   TEXT NOT NULL,
    left_scene        TEXT NOT NULL,
    right_scene       TEXT NOT NULL,
    left_stimulus     TEXT NOT NULL,             -- file name in <data-dir>/stimuli/
    right_stimulus    TEXT NOT NULL,
    catch_expected    TEXT CHECK (catch_expected IN ('left', 'right')),  -- NULL: not a catch trial
    shown_at          TEXT,                      -- first time the trial was sent to the participant
    PRIMARY KEY (participant, trial)
) STRICT, WITHOUT ROWID;

CREATE TABLE responses (
    participant       TEXT NOT NULL,
    trial             INTEGER NOT NULL,
    chosen            TEXT NOT NULL CHECK (chosen IN ('left', 'right')),
    rt_ms             REAL NOT NULL,
    client            TEXT NOT NULL,             -- JSON object
    answered_at       TEXT NOT NULL,
    PRIMARY KEY (participant, trial),
    FOREIGN KEY (participant, trial) REFERENCES trials (participant, trial)
) STRICT, WITHOUT ROWID;
