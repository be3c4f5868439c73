"""From photos or a video to a capture folder: frames, structure from motion (pycolmap), files."""
