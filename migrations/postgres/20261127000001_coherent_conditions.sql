-- Coherent conditions in the lab (issue 18; the sqlite migration of the same name says why):
-- the CHECK on `condition` of `task_trials` and `task_frame_times` admits Rohmer et al.'s
-- coherent methods beside none, shadows and gi.
ALTER TABLE task_trials DROP CONSTRAINT task_trials_condition_check;
ALTER TABLE task_trials ADD CONSTRAINT task_trials_condition_check CHECK (condition IN ('none', 'shadows', 'gi',
    'em', 'em-low', 'em-med', 'em-high', 'dit', 'dit-low', 'dit-med', 'dit-high',
    'vct', 'vct-low', 'vct-med', 'vct-high'));
ALTER TABLE task_frame_times DROP CONSTRAINT task_frame_times_condition_check;
ALTER TABLE task_frame_times ADD CONSTRAINT task_frame_times_condition_check CHECK (condition IN ('none', 'shadows', 'gi',
    'em', 'em-low', 'em-med', 'em-high', 'dit', 'dit-low', 'dit-med', 'dit-high',
    'vct', 'vct-low', 'vct-med', 'vct-high'));
