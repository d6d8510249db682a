"""Tests of jobs: lifecycle, workers, progress, cancel, crash recovery, downloads and `metairl serve`."""
