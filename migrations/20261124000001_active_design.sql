-- Active designs (issue 14): a study with `pairs = "active"` chooses each participant's trials in
-- batches from every judgment so far. What lets a researcher replay that choice:

-- The order in which responses were committed (1, 2, …, over the whole database): the posterior
-- absorbs judgments in this order, so "the state after N judgments" is well defined.
-- Responses stored before this migration are numbered in the order they were answered.
ALTER TABLE responses ADD COLUMN seq INTEGER;
UPDATE responses SET seq = (
    SELECT COUNT(*) FROM responses r2
    WHERE r2.answered_at < responses.answered_at
       OR (r2.answered_at = responses.answered_at
           AND (r2.participant < responses.participant
                OR (r2.participant = responses.participant AND r2.trial <= responses.trial))));
CREATE UNIQUE INDEX responses_seq ON responses (seq);

-- Which posterior state chose an actively chosen trial: `<judgments absorbed>-<fingerprint>`
-- (NULL for trials planned at join: a fixed design, the warm-up, catch trials), or the reason
-- the fixed design was used instead. `active_batch` numbers the participant's batches from 0.
ALTER TABLE trials ADD COLUMN chosen_by TEXT;
ALTER TABLE trials ADD COLUMN active_batch INTEGER;
