-- Lab participants managed like the survey's (issues 45 and 46; the sqlite migration of the same
-- name says why): pilot, exclusion, the participant's fixed pace and the late frames per trial.
ALTER TABLE task_participants ADD COLUMN pilot INTEGER NOT NULL DEFAULT 0 CHECK (pilot IN (0, 1));
ALTER TABLE task_participants ADD COLUMN excluded INTEGER NOT NULL DEFAULT 0 CHECK (excluded IN (0, 1));
ALTER TABLE task_participants ADD COLUMN exclusion_reason TEXT;
ALTER TABLE task_participants ADD COLUMN excluded_at TEXT;
ALTER TABLE task_participants ADD COLUMN pace_ms DOUBLE PRECISION;
ALTER TABLE task_trials ADD COLUMN frames_late INTEGER;
