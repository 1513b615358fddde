"""Animation: timelines of AU keys, the method's sequence, and AU data from trackers (OpenFace, Py-Feat,
Live Link, FAS) read into timelines."""
