-- Rating trials (issue 49, item 2: `kind = "rating"`): a response is a paired comparison's
-- `chosen` side or a rating from 1 to 5, exactly one of the two. `responses.chosen` was NOT NULL
-- with a CHECK; sqlite can alter neither, so `responses` is rebuilt with `chosen` nullable, the
-- new `rating` column and the CHECK that exactly one of them is set, and every row copied
-- (nothing references `responses`). `trials` gains `catch_rating`: the expected rating of a
-- rating study's catch trial (NULL: not one).

CREATE TABLE responses_rebuilt (
    participant       TEXT NOT NULL,
    trial             INTEGER NOT NULL,
    chosen            TEXT CHECK (chosen IN ('left', 'right', 'tie')),
    rt_ms             REAL NOT NULL,
    client            TEXT NOT NULL,             -- JSON object
    answered_at       TEXT NOT NULL,
    too_fast          INTEGER NOT NULL DEFAULT 0 CHECK (too_fast IN (0, 1)),
    served_ms         REAL,
    seq               INTEGER,
    display_css       TEXT,
    display_device    TEXT,
    rating            INTEGER CHECK (rating BETWEEN 1 AND 5),
    PRIMARY KEY (participant, trial),
    FOREIGN KEY (participant, trial) REFERENCES trials (participant, trial),
    CHECK ((chosen IS NULL) <> (rating IS NULL))
) STRICT, WITHOUT ROWID;
INSERT INTO responses_rebuilt (
    participant, trial, chosen, rt_ms, client, answered_at, too_fast, served_ms, seq, display_css, display_device
)
SELECT participant, trial, chosen, rt_ms, client, answered_at, too_fast, served_ms, seq, display_css, display_device
FROM responses;
DROP TABLE responses;
ALTER TABLE responses_rebuilt RENAME TO responses;
CREATE UNIQUE INDEX responses_seq ON responses (seq);

ALTER TABLE trials ADD COLUMN catch_rating INTEGER CHECK (catch_rating BETWEEN 1 AND 5);
