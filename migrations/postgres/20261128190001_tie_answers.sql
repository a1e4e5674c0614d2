-- "Not sure" (issue 49, item 3; the sqlite migration of the same name says why): the CHECK on
-- `responses.chosen` admits 'tie' beside 'left' and 'right'.
ALTER TABLE responses DROP CONSTRAINT responses_chosen_check;
ALTER TABLE responses ADD CONSTRAINT responses_chosen_check CHECK (chosen IN ('left', 'right', 'tie'));
