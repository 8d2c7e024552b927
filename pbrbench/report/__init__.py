"""The HTML report of a benchmark run (:mod:`.html`) and its figures (:mod:`.figures`)."""
