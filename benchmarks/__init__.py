TOPICS = ("branches",)
