// implemented by its issue-2 task
