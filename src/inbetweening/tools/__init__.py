"""Animator tools: the Inbetweener API, predict, export, render."""
