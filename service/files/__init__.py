"""Bytes in and out: `.npz` archives, CSV uploads (`csv_rows`, `csv_demonstrations`), reward downloads as
`.npy`/CSV/JSON with their names and ETags (`exports`), PNG heatmaps and matrices (`images`).

No database here: functions take and return arrays, bytes and text.
"""
