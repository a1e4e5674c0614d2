-- The size a trial's images were actually shown at (issue 45, item 3), sent by the page with the
-- response: `display_css` in CSS pixels and `display_device` in device pixels (CSS size times the
-- device pixel ratio), each `WxH` of one image (both images of a pair are shown at one scale).
-- NULL for a response sent without it (an API client, a page from before this migration).

ALTER TABLE responses ADD COLUMN display_css TEXT;
ALTER TABLE responses ADD COLUMN display_device TEXT;
