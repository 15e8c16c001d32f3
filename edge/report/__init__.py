"""What a verb shows a person: log helpers (``logs``), progress bars (``progress``) and plots
drawn with OpenCV (``plots``)."""
