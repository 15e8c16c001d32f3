"""Labelled data: the one label reader (``labels``), datasets in the paper authors' layout
(``dataset``) and the paper's error metrics (``metrics``)."""
