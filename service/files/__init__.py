"""Bytes in and out: `.npz` archives, CSV uploads (`csv_rows`, `csv_demonstrations`), recording files
(`recording_samples`, `force_plates`; C3D read in a child process by `c3d`/`c3d_reader`), reward downloads as
`.npy`/CSV/JSON with their names and ETags (`exports`), PNG heatmaps and matrices (`images`).

No database here: functions take and return arrays, bytes and text.
"""
