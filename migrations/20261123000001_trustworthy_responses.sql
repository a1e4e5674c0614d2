-- Trustworthy responses (issue "every stored answer is one a participant gave on purpose"):
-- pilot and excluded participants, one run per external id, screen-outs, preview links,
-- responses flagged too fast, and an audit log of data deletions without personal data.
-- Timestamps as in the initial migration (UTC, ISO 8601 with milliseconds).

-- A participant who joined through an admin preview link (never in the default analysis or export).
ALTER TABLE participants ADD COLUMN pilot INTEGER NOT NULL DEFAULT 0 CHECK (pilot IN (0, 1));
-- Excluded by the researcher (kept, never deleted; left out of analysis and export by default).
ALTER TABLE participants ADD COLUMN excluded INTEGER NOT NULL DEFAULT 0 CHECK (excluded IN (0, 1));
ALTER TABLE participants ADD COLUMN exclusion_reason TEXT;
ALTER TABLE participants ADD COLUMN excluded_at TEXT;
-- The external id (e.g. PROLIFIC_PID) when the study says `unique_external_id = true`: a
-- second join with the same id resumes this participant.
ALTER TABLE participants ADD COLUMN external_key TEXT;
CREATE UNIQUE INDEX participants_external_key ON participants (study, external_key)
    WHERE external_key IS NOT NULL;

-- Flagged when faster than the study's `min_response_ms`, by the client's response time or by
-- the server's own clock from serving the trial to receiving the answer (never dropped).
ALTER TABLE responses ADD COLUMN too_fast INTEGER NOT NULL DEFAULT 0 CHECK (too_fast IN (0, 1));
-- The server's time from first serving the trial to receiving the answer, ms.
ALTER TABLE responses ADD COLUMN served_ms REAL;

-- Visitors who did not meet the study's screen requirements (viewport, device, orientation):
-- counted in the dropout funnel; no demographics are asked before the screen check.
CREATE TABLE screen_outs (
    id                TEXT PRIMARY KEY,          -- random, 128 bits, hex
    study             TEXT NOT NULL REFERENCES studies (slug),
    reason            TEXT NOT NULL,             -- the sentence the visitor was shown
    client            TEXT NOT NULL,             -- JSON object: viewport, device, …
    url_params        TEXT NOT NULL,             -- JSON object: kept crowdsourcing parameters
    pilot             INTEGER NOT NULL DEFAULT 0 CHECK (pilot IN (0, 1)),
    created_at        TEXT NOT NULL
) STRICT;

-- Admin preview links: a participant who joins with one of these tokens is a pilot.
CREATE TABLE previews (
    token_sha256      BLOB PRIMARY KEY,
    study             TEXT NOT NULL REFERENCES studies (slug),
    created_at        TEXT NOT NULL
) STRICT;

-- What the researcher did to participants' data (exclude, include, delete): no personal data,
-- only the study, the participant's ordinal and counts.
CREATE TABLE audit (
    id                INTEGER PRIMARY KEY,
    at                TEXT NOT NULL,
    action            TEXT NOT NULL,
    study             TEXT NOT NULL,
    detail            TEXT NOT NULL
) STRICT;
