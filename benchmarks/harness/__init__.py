"""What every benchmark shares, and what ``tactile-force bench`` runs on a robot host (the core
install only: numpy, onnxruntime, OpenCV; never torch, onnx or matplotlib).

- :mod:`.paths`: the repository (a clone, or none when installed), the cache, the shared data;
- :mod:`.sources`: in-memory and paced frame sources;
- :mod:`.frames`: virtual DIGIT frames in contact, the virtual DIGIT's depth stage;
- :mod:`.latency`: per-stage latency through ``ForceRuntime``, a bare session beside it;
- :mod:`.budget`: the verdict against a latency budget while the machine is watched;
- :mod:`.machine`: the machine, its load, the header every page starts with;
- :mod:`.stats`: percentiles and Markdown tables;
- :mod:`.data`: readers of the shared real sensor data, labelled frames as arrays;
- :mod:`.cases`: a robustness case's outcome, the CLI run in-process;

Nothing here imports the docs pages, the bundle builders or the robustness suite.
"""
