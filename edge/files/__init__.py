"""Writing a verb's outputs without losing a user's files: ``guard`` refuses an output that
would destroy an input or replace something unasked; ``atomic`` publishes an output whole."""
