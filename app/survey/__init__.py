"""User studies after the CPS paper (SPEC F): questionnaires, protocol, counterbalancing,
an append-only answer store, and the analysis. No Qt here: the window parts are ui/survey_*.py.
"""
