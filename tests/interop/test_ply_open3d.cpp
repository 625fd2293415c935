// tests written by their issue-2 task
