-- Lab hygiene (issue 12, task studies): counterbalancing slots that an abandoned participant
-- gives up, the participant's last activity, the frames a participant actually saw per trial,
-- the frame time they saw (rendering plus pacing), and the frame time of every condition
-- measured when the lab starts. Timestamps as in the initial migration (UTC, ISO 8601 with ms).

-- The counterbalancing slot: the row of the Williams design (or Latin square) is picked by
-- `slot`, no longer by `ordinal` (which stays unique, in order of joining). A new participant
-- takes the slot of the longest-abandoned participant, else the next unused one.
ALTER TABLE task_participants ADD COLUMN slot INTEGER;
UPDATE task_participants SET slot = ordinal;
-- Last start, resume or stored answer; a participant who has not finished and has been inactive
-- for longer than the study's `abandon_after_minutes` is abandoned.
ALTER TABLE task_participants ADD COLUMN last_active_at TEXT;
UPDATE task_participants SET last_active_at = COALESCE(
    (SELECT MAX(t.answered_at) FROM task_trials t WHERE t.participant = task_participants.id),
    created_at);
-- When the participant's slot was given to another participant (they can no longer resume).
ALTER TABLE task_participants ADD COLUMN abandoned_at TEXT;
-- The participant who took over the slot.
ALTER TABLE task_participants ADD COLUMN slot_taken_by TEXT;
CREATE INDEX task_participants_slot ON task_participants (study, slot);

-- Frames of the trial the page reported as shown (the answer is refused until one is).
ALTER TABLE task_trials ADD COLUMN frames_shown INTEGER;
-- When the page reported the trial's first frame shown (server clock); completion time and
-- min_response_ms count from here.
ALTER TABLE task_trials ADD COLUMN shown_at TEXT;
-- Per frame, its request (trial start or key) → sent, ms: rendering, queueing and pacing — the
-- frame time the participant saw; the mean over the trial's frames.
ALTER TABLE task_trials ADD COLUMN shown_frame_ms_mean REAL;
-- The frame time every frame was paced to (pace = "equal"), ms; NULL when not paced.
ALTER TABLE task_trials ADD COLUMN paced_ms REAL;

-- Frame time per condition measured when `serve` starts the lab (a few frames each).
CREATE TABLE task_frame_times (
    study             TEXT NOT NULL REFERENCES studies (slug),
    measured_at       TEXT NOT NULL,
    adapter           TEXT NOT NULL,
    condition         TEXT NOT NULL CHECK (condition IN ('none', 'shadows', 'gi')),
    width             INTEGER NOT NULL,
    height            INTEGER NOT NULL,
    frames            INTEGER NOT NULL,
    median_ms         REAL NOT NULL,           -- render + encode
    PRIMARY KEY (study, measured_at, condition)
) STRICT;
