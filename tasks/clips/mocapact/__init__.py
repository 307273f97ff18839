"""Package data from MoCapAct: its snippet list of the CMU 2020 clips (see NOTICE.txt).

Read through :func:`tasks.clips.snippets.mocapact_snippets`.
"""
