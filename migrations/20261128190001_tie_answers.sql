-- "Not sure" (issue 49, item 3): a study with `allow_tie = true` offers a third answer in its
-- paired comparisons, stored as `chosen = 'tie'`. The CHECK on `responses.chosen` allowed only
-- 'left' and 'right'; sqlite cannot alter a CHECK, so the table is rebuilt with the wider one
-- and every row copied (nothing references `responses`).

CREATE TABLE responses_rebuilt (
    participant       TEXT NOT NULL,
    trial             INTEGER NOT NULL,
    chosen            TEXT NOT NULL CHECK (chosen IN ('left', 'right', 'tie')),
    rt_ms             REAL NOT NULL,
    client            TEXT NOT NULL,             -- JSON object
    answered_at       TEXT NOT NULL,
    too_fast          INTEGER NOT NULL DEFAULT 0 CHECK (too_fast IN (0, 1)),
    served_ms         REAL,
    seq               INTEGER,
    display_css       TEXT,
    display_device    TEXT,
    PRIMARY KEY (participant, trial),
    FOREIGN KEY (participant, trial) REFERENCES trials (participant, trial)
) STRICT, WITHOUT ROWID;
INSERT INTO responses_rebuilt (
    participant, trial, chosen, rt_ms, client, answered_at, too_fast, served_ms, seq, display_css, display_device
)
SELECT participant, trial, chosen, rt_ms, client, answered_at, too_fast, served_ms, seq, display_css, display_device
FROM responses;
DROP TABLE responses;
ALTER TABLE responses_rebuilt RENAME TO responses;
CREATE UNIQUE INDEX responses_seq ON responses (seq);
