-- Lab participants managed like the survey's (issues 45 and 46): a lab participant is created
-- over HTTP (`POST /api/lab/{slug}/participants`) before its WebSocket session starts, may be a
-- pilot (joined through a preview link), may be excluded (kept, with the reason and the time)
-- and deleted. Its frames are paced to one frame time, fixed when the participant is created and
-- kept for all its sessions; per trial, the frames that reached the participant later than that
-- pace (by more than 10 %) are counted, so a session that could not keep its pace is flagged.
-- Timestamps as in the initial migration (UTC, ISO 8601 with milliseconds).

ALTER TABLE task_participants ADD COLUMN pilot INTEGER NOT NULL DEFAULT 0 CHECK (pilot IN (0, 1));
ALTER TABLE task_participants ADD COLUMN excluded INTEGER NOT NULL DEFAULT 0 CHECK (excluded IN (0, 1));
ALTER TABLE task_participants ADD COLUMN exclusion_reason TEXT;
ALTER TABLE task_participants ADD COLUMN excluded_at TEXT;
-- The frame time every frame of this participant is held to (pace = "equal"), ms; NULL: not paced.
ALTER TABLE task_participants ADD COLUMN pace_ms REAL;
-- Frames of the trial that reached the participant more than 10 % later than the pace.
ALTER TABLE task_trials ADD COLUMN frames_late INTEGER;
