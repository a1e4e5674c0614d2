-- Rating trials (issue 49, item 2; the sqlite migration of the same name says why): a response
-- holds a `chosen` side or a `rating` from 1 to 5, exactly one; `trials.catch_rating` is the
-- expected rating of a rating study's catch trial.
ALTER TABLE responses ALTER COLUMN chosen DROP NOT NULL;
ALTER TABLE responses ADD COLUMN rating INTEGER CHECK (rating BETWEEN 1 AND 5);
ALTER TABLE responses ADD CONSTRAINT responses_one_answer CHECK ((chosen IS NULL) <> (rating IS NULL));
ALTER TABLE trials ADD COLUMN catch_rating INTEGER CHECK (catch_rating BETWEEN 1 AND 5);
