-- The size a trial's images were actually shown at (issue 45, item 3), as in the sqlite
-- migration of the same name: `WxH` in CSS pixels and in device pixels, NULL when not sent.

ALTER TABLE responses ADD COLUMN display_css TEXT;
ALTER TABLE responses ADD COLUMN display_device TEXT;
